/* ssiu-flight-demo DIR [--frames N] [--json FILE] [--csv FILE]
 *
 * Replays a mission written by `ssiu run --out DIR --write-frames` through the C interface only
 * (ssiu_flight.h), as a flight program would: everything is allocated at start (the handle's memory,
 * the catalog blob, one frame buffer per head), then the loop feeds gyro samples and frames in time
 * order with open/read into those buffers and allocates nothing. It writes a JSON summary
 * (frames_processed, status, attitude_error_arcsec against DIR/truth.csv, frame_ms_mean,
 * frame_ms_max, ...) and with --csv one row per frame set (t_s, statuses, matches, attitude).
 * docs/flight.md.
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "ssiu_flight.h"

#define MAX_LINE 1024

static void die(const char* file, const char* what) {
  fprintf(stderr, "ssiu-flight-demo: %s: %s\n", file, what);
  exit(1);
}

/* The whole of a (small) file, read at start. */
static char* read_all(const char* path, size_t* bytes) {
  int fd = open(path, O_RDONLY);
  if (fd < 0) die(path, strerror(errno));
  off_t end = lseek(fd, 0, SEEK_END);
  if (end < 0 || lseek(fd, 0, SEEK_SET) != 0) die(path, "cannot seek");
  char* buf = malloc((size_t)end + 1);
  if (!buf) die(path, "out of memory");
  size_t got = 0;
  while (got < (size_t)end) {
    ssize_t n = read(fd, buf + got, (size_t)end - got);
    if (n <= 0) die(path, "short read");
    got += (size_t)n;
  }
  close(fd);
  buf[got] = 0;
  *bytes = got;
  return buf;
}

/* A CSV read line by line through one stdio stream opened at start (its buffer is made then). */
typedef struct {
  FILE* f;
  const char* path;
  char line[MAX_LINE];
  long row;
} csv_reader;

static void csv_open(csv_reader* r, const char* path) {
  r->path = path;
  r->row = 0;
  r->f = fopen(path, "r");
  if (!r->f) die(path, strerror(errno));
  if (!fgets(r->line, sizeof r->line, r->f)) die(path, "empty file");  /* the header */
}

/* The next row's first n numbers; 0 at the end. */
static int csv_next(csv_reader* r, double* v, int n) {
  if (!fgets(r->line, sizeof r->line, r->f)) return 0;
  ++r->row;
  char* p = r->line;
  for (int i = 0; i < n; ++i) {
    char* end = NULL;
    v[i] = strtod(p, &end);
    if (end == p) die(r->path, "a row with too few numbers");
    p = end;
    if (*p == ',') ++p;
  }
  return 1;
}

/* One 16-bit binary PGM (P5, maxval 65535) into `pixels` (width x height), read with one open/read
 * into `raw` (header + data): no allocation. */
static int read_pgm(const char* path, uint8_t* raw, size_t raw_bytes, uint16_t* pixels, int width, int height) {
  int fd = open(path, O_RDONLY);
  if (fd < 0) return 0;
  size_t got = 0;
  for (;;) {
    ssize_t n = read(fd, raw + got, raw_bytes - got);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    got += (size_t)n;
    if (got == raw_bytes) break;
  }
  close(fd);
  int w = 0, h = 0, maxval = 0, off = 0;
  char head[64];
  size_t hb = got < sizeof head - 1 ? got : sizeof head - 1;
  memcpy(head, raw, hb);
  head[hb] = 0;
  if (sscanf(head, "P5 %d %d %d%n", &w, &h, &maxval, &off) != 3 || w != width || h != height || maxval != 65535)
    return 0;
  off += 1; /* the single whitespace after maxval */
  if ((size_t)off + 2u * (size_t)w * (size_t)h > got) return 0;
  const uint8_t* d = raw + off;
  for (size_t i = 0; i < (size_t)w * (size_t)h; ++i) pixels[i] = (uint16_t)((d[2 * i] << 8) | d[2 * i + 1]);
  return 1;
}

static double now_ms(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

/* Angle (arcsec) of q_est * conj(q_true), both [w, x, y, z]. */
static double error_arcsec(const double* a, const double* b) {
  const double w = a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3];
  const double x = -a[0] * b[1] + a[1] * b[0] - a[2] * b[3] + a[3] * b[2];
  const double y = -a[0] * b[2] + a[2] * b[0] - a[3] * b[1] + a[1] * b[3];
  const double z = -a[0] * b[3] + a[3] * b[0] - a[1] * b[2] + a[2] * b[1];
  const double rad_to_arcsec = 648000.0 / 3.14159265358979323846;
  return 2 * atan2(sqrt(x * x + y * y + z * z), fabs(w)) * rad_to_arcsec;
}

static const char* status_name(int32_t s) { return s == 0 ? "ok" : s == 1 ? "degraded" : "failed"; }

int main(int argc, char** argv) {
  const char *dir = NULL, *json = NULL, *csv = NULL;
  long max_frames = -1;
  for (int i = 1; i < argc; ++i) {
    if (!strcmp(argv[i], "--frames") && i + 1 < argc) {
      char* end = NULL;
      max_frames = strtol(argv[++i], &end, 10);
      if (*end || max_frames < 0) die("--frames", "must be a count >= 0");
    } else if (!strcmp(argv[i], "--json") && i + 1 < argc) {
      json = argv[++i];
    } else if (!strcmp(argv[i], "--csv") && i + 1 < argc) {
      csv = argv[++i];
    } else if (argv[i][0] != '-' && !dir) {
      dir = argv[i];
    } else {
      fprintf(stderr, "usage: ssiu-flight-demo DIR [--frames N] [--json FILE] [--csv FILE]\n");
      return 1;
    }
  }
  if (!dir) {
    fprintf(stderr, "usage: ssiu-flight-demo DIR [--frames N] [--json FILE] [--csv FILE]\n");
    return 1;
  }
  char path[4096];

  /* Start-up: configuration, catalog blob, memory, buffers. */
  snprintf(path, sizeof path, "%s/flight.cfg", dir);
  size_t cfg_bytes = 0;
  char* cfg_text = read_all(path, &cfg_bytes);
  ssiu_flight_config cfg;
  char why[512];
  if (ssiu_flight_parse_config(cfg_text, cfg_bytes, &cfg, why, sizeof why) != SSIU_OK) die(path, why);
  free(cfg_text);
  snprintf(path, sizeof path, "%s/catalog/catalog.bin", dir);
  size_t catalog_bytes = 0;
  char* catalog = read_all(path, &catalog_bytes);
  size_t mem_bytes = ssiu_flight_memory_bytes(&cfg);
  if (mem_bytes == 0) die("flight.cfg", "configuration refused by ssiu_flight_check_config");
  void* memory = aligned_alloc(16, (mem_bytes + 15) / 16 * 16);
  if (!memory) die("memory", "out of memory");
  ssiu_flight* f = NULL;
  ssiu_result rc = ssiu_flight_init(&cfg, catalog, catalog_bytes, memory, mem_bytes, &f);
  if (rc != SSIU_OK) die("init", (const char*)memory);

  uint16_t* pixels[SSIU_FLIGHT_MAX_HEADS] = {0};
  size_t raw_bytes = 0;
  for (int h = 0; h < cfg.n_heads; ++h) {
    size_t n = (size_t)cfg.heads[h].width_px * (size_t)cfg.heads[h].height_px;
    pixels[h] = malloc(n * sizeof(uint16_t));
    if (!pixels[h]) die("frames", "out of memory");
    if (2 * n + 64 > raw_bytes) raw_bytes = 2 * n + 64;
  }
  uint8_t* raw = malloc(raw_bytes);
  if (!raw) die("frames", "out of memory");

  csv_reader gyro, frames;
  snprintf(path, sizeof path, "%s/gyro.csv", dir);
  char gyro_path[4096];
  memcpy(gyro_path, path, sizeof path);
  csv_open(&gyro, gyro_path);
  char frames_path[4096];
  snprintf(frames_path, sizeof frames_path, "%s/frames.csv", dir);
  csv_open(&frames, frames_path);
  FILE* out_csv = NULL;
  if (csv) {
    out_csv = fopen(csv, "w");
    if (!out_csv) die(csv, strerror(errno));
    fprintf(out_csv, "t_s,status,heads_solved");
    for (int h = 1; h <= cfg.n_heads; ++h) fprintf(out_csv, ",head%d_status,head%d_matches", h, h);
    fprintf(out_csv, ",qw,qx,qy,qz\n");
  }

  /* The loop: gyro samples in time order, each frame time processed before the first sample after
   * it and after a sample at the same time (as `ssiu run` feeds the processor). */
  double g[1 + SSIU_FLIGHT_MAX_GYROS];
  double t_frame = 0;
  int have_frame = csv_next(&frames, &t_frame, 1);
  long frame_index = 0, processed = 0;
  double ms_sum = 0, ms_max = 0;
  int have_gyro = csv_next(&gyro, g, 1 + cfg.n_gyros);
  for (;;) {
    int limit = max_frames >= 0 && processed >= max_frames;
    /* The next event: a frame set when its time is before the next gyro sample. */
    if (have_frame && !limit && (!have_gyro || t_frame < g[0] - 1e-9)) {
      ssiu_frame fr[SSIU_FLIGHT_MAX_HEADS];
      memset(fr, 0, sizeof fr);
      for (int h = 0; h < cfg.n_heads; ++h) {
        snprintf(path, sizeof path, "%s/frames/head%d_%05ld.pgm", dir, h + 1, frame_index);
        fr[h].width_px = cfg.heads[h].width_px;
        fr[h].height_px = cfg.heads[h].height_px;
        if (read_pgm(path, raw, raw_bytes, pixels[h], fr[h].width_px, fr[h].height_px)) fr[h].pixels = pixels[h];
      }
      ssiu_frame_report rep;
      const double t0 = now_ms();
      rc = ssiu_flight_frames(f, t_frame, fr, cfg.n_heads, &rep);
      const double ms = now_ms() - t0;
      if (rc != SSIU_OK) die("frames", ssiu_flight_last_error(f));
      ms_sum += ms;
      if (ms > ms_max) ms_max = ms;
      if (out_csv) {
        fprintf(out_csv, "%.9g,%d,%d", rep.t_s, rep.status, rep.heads_solved);
        for (int h = 0; h < cfg.n_heads; ++h) fprintf(out_csv, ",%d,%d", rep.heads[h].status, rep.heads[h].matches);
        fprintf(out_csv, ",%.17g,%.17g,%.17g,%.17g\n", rep.q_inertial_from_body[0], rep.q_inertial_from_body[1],
                rep.q_inertial_from_body[2], rep.q_inertial_from_body[3]);
      }
      ++processed;
      ++frame_index;
      have_frame = csv_next(&frames, &t_frame, 1);
      continue;
    }
    /* After the last frame set asked for, the gyro samples up to the next frame's time. */
    if (!have_gyro || (limit && have_frame && g[0] > t_frame + 1e-9)) break;
    ssiu_gyro_status gs;
    rc = ssiu_flight_gyro(f, g[0], g + 1, cfg.n_gyros, &gs);
    if (rc != SSIU_OK) die("gyro", ssiu_flight_last_error(f));
    have_gyro = csv_next(&gyro, g, 1 + cfg.n_gyros);
  }

  ssiu_state st;
  if (ssiu_flight_state(f, &st) != SSIU_OK) die("state", "no state");
  /* The truth at the state's time (the gyro sample it was propagated to). */
  csv_reader truth;
  char truth_path[4096];
  snprintf(truth_path, sizeof truth_path, "%s/truth.csv", dir);
  csv_open(&truth, truth_path);
  double row[5], best[5] = {0, 1, 0, 0, 0};
  double best_dt = INFINITY;
  while (csv_next(&truth, row, 5)) {
    if (fabs(row[0] - st.t_s) < best_dt) {
      best_dt = fabs(row[0] - st.t_s);
      memcpy(best, row, sizeof row);
    }
  }
  const double err = st.valid ? error_arcsec(st.q_inertial_from_body, best + 1) : NAN;
  printf("ssiu-flight-demo: %ld frame sets (%lld solved), %lld gyro samples (%lld refused), status %s, "
         "final attitude error %.2f arcsec, %.3f ms per frame set (max %.3f)\n",
         processed, (long long)st.frame_sets_solved, (long long)st.gyro_samples, (long long)st.gyro_rejected,
         status_name(st.status), err, processed ? ms_sum / processed : 0.0, ms_max);
  if (json) {
    FILE* j = strcmp(json, "-") ? fopen(json, "w") : stdout;
    if (!j) die(json, strerror(errno));
    fprintf(j,
            "{\n  \"frames_processed\": %ld,\n  \"frames_solved\": %lld,\n  \"gyro_samples\": %lld,\n"
            "  \"gyro_rejected\": %lld,\n  \"status\": \"%s\",\n  \"valid\": %s,\n",
            processed, (long long)st.frame_sets_solved, (long long)st.gyro_samples, (long long)st.gyro_rejected,
            status_name(st.status), st.valid ? "true" : "false");
    if (st.valid)
      fprintf(j, "  \"attitude_error_arcsec\": %.6f,\n", err);
    else
      fprintf(j, "  \"attitude_error_arcsec\": null,\n");
    fprintf(j,
            "  \"t_s\": %.9g,\n  \"q_inertial_from_body\": [%.17g, %.17g, %.17g, %.17g],\n"
            "  \"bias_dph\": [%.9g, %.9g, %.9g],\n  \"frame_ms_mean\": %.6f,\n  \"frame_ms_max\": %.6f,\n"
            "  \"version\": \"%s\"\n}\n",
            st.t_s, st.q_inertial_from_body[0], st.q_inertial_from_body[1], st.q_inertial_from_body[2],
            st.q_inertial_from_body[3], st.bias_dph[0], st.bias_dph[1], st.bias_dph[2],
            processed ? ms_sum / processed : 0.0, ms_max, ssiu_flight_version());
    if (j != stdout) fclose(j);
  }
  if (out_csv) fclose(out_csv);
  fclose(gyro.f);
  fclose(frames.f);
  fclose(truth.f);
  ssiu_flight_shutdown(f);
  free(memory);
  free(catalog);
  free(raw);
  for (int h = 0; h < cfg.n_heads; ++h) free(pixels[h]);
  return 0;
}
