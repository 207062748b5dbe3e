/* ssiu_flight.h: the C interface of the unit's processor (docs/flight.md).
 *
 * C99, plain structs and fixed-size arrays, every failure a status. One handle runs the whole loop of
 * the star-inertial unit: star frames of 1-3 optical heads (detect -> identify, lost in space and then
 * tracking -> QUEST over all heads) fused with a four-FOG unit in the MEKF with fault detection.
 *
 *   ssiu_flight_config cfg;
 *   ssiu_flight_default_config(&cfg);               // the default two-head unit; change what differs
 *   size_t need = ssiu_flight_memory_bytes(&cfg);   // the handle and every workspace
 *   ssiu_flight* f = NULL;
 *   if (ssiu_flight_init(&cfg, catalog_blob, catalog_bytes, memory, need, &f) != SSIU_OK) ...
 *   ssiu_flight_gyro(f, t_s, g_dph, 4, &gyro_status);                 // every gyro sample
 *   ssiu_flight_frames(f, t_s, frames, cfg.n_heads, &report);          // every set of frames
 *   ssiu_flight_state(f, &state);                                      // attitude, covariance, biases
 *   ssiu_flight_shutdown(f);
 *
 * Conventions (../shared/docs/conventions.md): quaternions Hamilton [w, x, y, z], w >= 0, rotating
 * vectors from the body (or sensor) frame to the inertial frame (ICRS); a gyro sample at t_s is the mean
 * rate over (t_prev, t_s]; a frame's t_s is the middle of its exposure; t_s counts seconds from the
 * epoch config.epoch_utc. Pixels: (0, 0) is the centre of the top-left pixel, x right, y down.
 * Rates in deg/h (_dph), angles in the names' units, covariances in rad^2.
 *
 * The handle is not thread-safe: one caller (a rate group) drives it. The catalog blob must stay
 * valid and unchanged while the handle lives.
 */
#ifndef SSIU_FLIGHT_H_
#define SSIU_FLIGHT_H_

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define SSIU_FLIGHT_MAX_HEADS 3
#define SSIU_FLIGHT_MAX_GYROS 6
#define SSIU_FLIGHT_MAX_FAULTS 8 /* fault events reported in the state (the first ones) */
#define SSIU_FLIGHT_MAX_HOT_PIXELS 256 /* known hot pixels listed per head */

typedef enum {
  SSIU_OK = 0,
  SSIU_ERR_NULL = 1,            /* a required pointer was NULL */
  SSIU_ERR_CONFIG = 2,          /* a configuration field is out of range (see ssiu_flight_last_error) */
  SSIU_ERR_CATALOG = 3,         /* the catalog blob is missing, corrupt or does not fit the heads */
  SSIU_ERR_MEMORY = 4,          /* the memory given is smaller than ssiu_flight_memory_bytes() */
  SSIU_ERR_NOT_INITIALISED = 5, /* the handle is not (or no longer) initialised */
  SSIU_ERR_ARGUMENT = 6,        /* a call's argument is wrong (e.g. the number of frames) */
  SSIU_ERR_INTERNAL = 7         /* a failure inside the processor; the call had no effect */
} ssiu_result;

/* What became of one gyro sample (the processor's GyroSampleStatus, docs/inertial.md "Bad inputs"). */
typedef enum {
  SSIU_GYRO_ACCEPTED = 0,
  SSIU_GYRO_REJECTED_NON_FINITE = 1,   /* NaN/inf outputs and the rest give no rate: the last rate held */
  SSIU_GYRO_REJECTED_OUT_OF_RANGE = 2, /* the same for outputs beyond gyro_max_abs_dph */
  SSIU_GYRO_REJECTED_OUT_OF_ORDER = 3, /* a time tag before the last one (state unchanged) */
  SSIU_GYRO_REJECTED_REPEATED = 4,     /* the last sample's time again (state unchanged) */
  SSIU_GYRO_PARTIAL = 5,               /* an output unusable: the rate from the other gyros in use */
  SSIU_GYRO_ACCEPTED_AFTER_GAP = 6,    /* confirms a time jump; the attitude restarts from the next star fix */
  SSIU_GYRO_REJECTED_BAD_TIME = 7,     /* a NaN/inf time tag (state unchanged) */
  SSIU_GYRO_REJECTED_WRONG_SIZE = 8,   /* not one output per gyro (state unchanged) */
  SSIU_GYRO_REJECTED_TIME_JUMP = 9,    /* far beyond the last sample: taken if the next one follows it */
  SSIU_GYRO_ACCEPTED_TIME_RESET = 10   /* the clock went back: its time taken, restart from the next fix */
} ssiu_gyro_status;

/* A head's or a frame set's result (the values of conventions.md's solve statuses, and more). */
typedef enum {
  SSIU_SOLVE_SOLVED = 0,        /* "solved" */
  SSIU_SOLVE_NO_MATCH = 1,      /* "no_match" */
  SSIU_SOLVE_TOO_FEW_STARS = 2, /* "too_few_stars" */
  SSIU_SOLVE_NO_FRAME = 3,      /* "no_frame": no frame from this head this time */
  SSIU_SOLVE_BAD_FRAME = 4      /* "bad_frame": wrong size or stride, or a bad time tag */
} ssiu_solve_status;

/* What the filter made of a frame set's solution (the processor's UpdateStatus). */
typedef enum {
  SSIU_UPDATE_ACCEPTED = 0,
  SSIU_UPDATE_INITIALISED = 1,        /* it started (or restarted) the filter */
  SSIU_UPDATE_REJECTED_NIS = 2,       /* beyond the innovation gate */
  SSIU_UPDATE_REJECTED_LATE = 3,      /* before the filter's time */
  SSIU_UPDATE_REJECTED_REPEATED = 4,  /* the same time as the last one */
  SSIU_UPDATE_REJECTED_BAD_INPUT = 5, /* a non-finite time, attitude or covariance */
  SSIU_UPDATE_REJECTED_TIME_JUMP = 6, /* too far beyond the filter's time, not (yet) confirmed */
  SSIU_UPDATE_NONE = 7                /* no solution to offer (nothing solved) */
} ssiu_update_status;

/* The fused attitude's trust (conventions: 0 ok, 1 degraded, 2 failed). */
typedef enum { SSIU_STATUS_OK = 0, SSIU_STATUS_DEGRADED = 1, SSIU_STATUS_FAILED = 2 } ssiu_status;

/* The in-flight calibration of the unit's scale factors and axis tilts (config calibrate_unit). */
typedef enum {
  SSIU_UNIT_CAL_OFF = 0,            /* not asked for */
  SSIU_UNIT_CAL_ACCUMULATING = 1,   /* fewer star windows than terms so far */
  SSIU_UNIT_CAL_NOT_OBSERVABLE = 2, /* the body has not yet turned about three independent axes */
  SSIU_UNIT_CAL_ESTIMATED = 3,      /* estimated, not applied */
  SSIU_UNIT_CAL_APPLIED = 4         /* the gyro outputs are corrected by the estimate */
} ssiu_unit_cal_status;

typedef struct {
  int32_t width_px, height_px;
  double focal_length_px;   /* fx */
  double focal_length_y_px; /* fy; 0 = square pixels (fy = fx) */
  double cx_px, cy_px;      /* principal point */
  double k1, k2, k3, p1, p2; /* Brown-Conrady distortion on normalised coordinates (OpenCV's) */
  double gain_e_per_adu;     /* 0 = unknown */
  double q_body_sensor[4];   /* [w, x, y, z]: rotates vectors from this head's sensor frame to the body */
  /* camera.json's fields beyond the geometry (conventions.md): the PSF's Gaussian sigma the detector
   * expects (0 = measured on each frame); the flux factor 1 - vignetting (r / r_corner)^2, taken out of
   * the centroid fluxes before identification (0 = none); the known persistent hot pixels [x, y],
   * repaired before detection (their map is made at init, in the caller's memory). */
  double psf_sigma_px;
  double vignetting;
  int32_t n_hot_pixels; /* 0..SSIU_FLIGHT_MAX_HOT_PIXELS */
  uint16_t hot_pixels_xy[SSIU_FLIGHT_MAX_HOT_PIXELS][2];
} ssiu_head_config;

typedef struct {
  double axis_body[3];             /* unit sensing axis */
  double arw_deg_per_sqrt_h;       /* angle random walk */
  double bias_instability_dph;     /* flicker floor */
  double rrw_dph_per_sqrt_h;       /* rate random walk */
} ssiu_gyro_config;

typedef struct {
  int32_t n_heads; /* 1..SSIU_FLIGHT_MAX_HEADS */
  ssiu_head_config heads[SSIU_FLIGHT_MAX_HEADS];
  int32_t n_gyros; /* 3..SSIU_FLIGHT_MAX_GYROS */
  ssiu_gyro_config gyros[SSIU_FLIGHT_MAX_GYROS];
  double gyro_rate_hz;       /* nominal sample rate */
  double gyro_max_abs_dph;   /* an output beyond this is unusable, like a NaN; 0 = 3.6e6 (1000 deg/s) */
  /* Sizes every buffer is made for at init. */
  int32_t max_centroids;       /* brightest detections kept per frame */
  int32_t max_stars_in_field;  /* catalog stars about a head's field that identification predicts from */
  int32_t max_star_samples;    /* star solutions a suspected gyro fault's isolator keeps (the oldest go first) */
  int32_t max_bias_history;    /* bias estimates kept for the fault fits (the oldest go first) */
  /* Identification. */
  int32_t max_hypotheses;      /* lost-in-space work budget: hypotheses checked (deterministic) */
  int32_t max_patterns;        /* and centroid triangles looked up: whichever comes first ends the search */
  double max_false_match_prob; /* accept a hypothesis only below this chance probability */
  double threshold_sigma;      /* detection threshold (noise sigmas) */
  double exposure_s;           /* frame exposure: the detector expects the smear of the gyro rate; 0 = off */
  double systematic_px;        /* unmodelled centroid error added in quadrature (px) */
  double track_search_radius_px;
  /* Time and sky: t_s = 0 is this UTC instant (ISO 8601, e.g. "2025-06-21T00:00:00Z"); "" = unknown,
   * no aberration or proper motion correction. */
  char epoch_utc[40];
  double velocity_kms[3]; /* spacecraft velocity relative to the Earth, ICRS (for aberration) */
  /* The catalog blob's CRC-32 (meta.json catalog_bin_crc32), required: checked at init. */
  uint32_t catalog_crc32;
  /* 1: estimate the unit's scale factors and axis tilts from the star attitudes and correct the gyro
   * outputs by them (4+ gyros; fixed memory and work, docs/inertial.md "In-flight calibration");
   * 0 (the default): the unit as configured. */
  int32_t calibrate_unit;
} ssiu_flight_config;

typedef struct {
  const uint16_t* pixels; /* NULL: no frame from this head this time */
  int32_t width_px, height_px;
  int32_t stride_px; /* pixels from one row to the next; 0 = width_px */
} ssiu_frame;

typedef struct {
  int32_t status;     /* ssiu_solve_status */
  int32_t lost_in_space; /* 1 when identified lost in space, 0 when by tracking */
  int32_t detections; /* stars detected */
  int32_t matches;    /* stars matched to the catalog */
  double sigma_cross_arcsec, sigma_roll_arcsec;
  double q_inertial_from_sensor[4]; /* when solved */
  /* The identification's chance probability of its matches (below max_false_match_prob when solved) and its
   * photometric evidence factor (1 = none), as `ssiu solve` reports them: telemetry of how sure it was. */
  double false_match_probability, photometric_factor;
} ssiu_head_report;

typedef struct {
  double t_s;
  int32_t status;      /* ssiu_solve_status of the set: solved when any head solved */
  int32_t heads_solved;
  ssiu_head_report heads[SSIU_FLIGHT_MAX_HEADS];
  double q_inertial_from_body[4]; /* the star-only body attitude, when solved */
  int32_t initialised_filter;     /* this set started (or restarted) the filter */
  int32_t update_accepted;        /* the filter took it */
  int32_t update_status;          /* ssiu_update_status */
  double nis;                     /* its normalised innovation squared */
} ssiu_frame_report;

typedef struct {
  int32_t gyro;    /* 1-based; 0 while not isolated */
  double t_onset_s, t_detect_s, t_isolate_s; /* t_isolate_s = -1 while not isolated */
  double fault_dph;
} ssiu_fault;

typedef struct {
  int32_t valid;  /* 0 until the first solved frame set */
  int32_t status; /* ssiu_status */
  double t_s;
  double q_inertial_from_body[4];
  double covariance_rad2[9]; /* attitude error, body axes, row-major */
  double bias_dph[3], bias_sigma_dph[3];
  uint32_t gyros_in_use; /* bit i: gyro i + 1 */
  int32_t n_faults;      /* events so far (those beyond SSIU_FLIGHT_MAX_FAULTS not listed) */
  ssiu_fault faults[SSIU_FLIGHT_MAX_FAULTS];
  int32_t restart_pending; /* the filter restarts from the next solved frame set (state not valid meanwhile) */
  int32_t restarts;        /* restarts so far (a non-finite state, a gyro gap, a clock reset) */
  /* Counts of inputs since init. */
  int64_t gyro_samples, gyro_rejected, gyro_partial, frame_sets, frame_sets_solved, frame_sets_refused;
  /* The in-flight unit calibration (config calibrate_unit): ssiu_unit_cal_status, the star windows it
   * used, and per gyro (0-based, n_gyros of them; zero until estimated) the scale factor correction (ppm)
   * and the axis' two tilts about its normals (arcsec), with their 1-sigma. */
  int32_t unit_cal_status;
  int32_t unit_cal_windows;
  double scale_factor_ppm[SSIU_FLIGHT_MAX_GYROS], scale_factor_sigma_ppm[SSIU_FLIGHT_MAX_GYROS];
  double misalignment_arcsec[SSIU_FLIGHT_MAX_GYROS][2], misalignment_sigma_arcsec[SSIU_FLIGHT_MAX_GYROS][2];
} ssiu_state;

typedef struct ssiu_flight ssiu_flight;

/* "MAJOR.MINOR.PATCH" of this library, and the interface's version (changes when a struct changes). */
const char* ssiu_flight_version(void);
int32_t ssiu_flight_interface_version(void);

/* The default unit: two 512x512 heads of 16.6 deg, 90 deg apart, the four-FOG unit at 100 Hz. */
void ssiu_flight_default_config(ssiu_flight_config* config);
/* A configuration from its text form (flight.cfg, written by `ssiu run --write-frames`: one `key
 * values...` a line, docs/flight.md), over the defaults. SSIU_ERR_CONFIG with the line and key in
 * `why` (why_bytes may be 0). For ground tools and start-up, not for the rate group. */
ssiu_result ssiu_flight_parse_config(const char* text, size_t bytes, ssiu_flight_config* config, char* why,
                                     size_t why_bytes);
/* SSIU_OK or SSIU_ERR_CONFIG (ssiu_flight_init's failure text names the field). */
ssiu_result ssiu_flight_check_config(const ssiu_flight_config* config);
/* Bytes of memory the handle needs for `config` (0 for a bad config): the handle and every workspace
 * (detection, identification, the fusion's fault monitors and histories), which init places in the
 * memory given instead of the heap. Measured by making the workspaces once on the heap and freeing
 * them: a start-up call, not for the rate group; it depends only on the configuration (and the
 * target: 32- and 64-bit builds differ), so a target without a heap can size a static block from
 * the same call made on the ground for the same build. */
size_t ssiu_flight_memory_bytes(const ssiu_flight_config* config);
/* Starts a handle in `memory` (at least ssiu_flight_memory_bytes(), aligned to 16 bytes; less is
 * SSIU_ERR_MEMORY), with the
 * catalog blob (catalog.bin of `ssiu catalog build`) read-only in memory or ROM; config.catalog_crc32
 * must be its CRC-32 (meta.json's catalog_bin_crc32): a blob that differs is refused before it is
 * read. On failure `memory` holds the reason as a NUL-terminated string. */
ssiu_result ssiu_flight_init(const ssiu_flight_config* config, const void* catalog_blob, size_t catalog_bytes,
                             void* memory, size_t memory_bytes, ssiu_flight** out);
/* One gyro sample: the n mean outputs (deg/h) over (t_prev, t_s]; `status` (may be NULL) says what
 * became of it. A bad sample is refused and the filter goes on. */
ssiu_result ssiu_flight_gyro(ssiu_flight* f, double t_s, const double* g_dph, int32_t n, ssiu_gyro_status* status);
/* One set of simultaneous frames at t_s: n == config.n_heads entries, one per head in head order
 * (pixels NULL for a head without a frame). `report` (may be NULL) gets what each head gave. */
ssiu_result ssiu_flight_frames(ssiu_flight* f, double t_s, const ssiu_frame* frames, int32_t n,
                               ssiu_frame_report* report);
ssiu_result ssiu_flight_state(const ssiu_flight* f, ssiu_state* state);
/* Ends the handle (its memory is the caller's again). */
void ssiu_flight_shutdown(ssiu_flight* f);
/* What the last failed call of this handle said ("" when none, or for no handle): never NULL. */
const char* ssiu_flight_last_error(const ssiu_flight* f);
/* A result's name for events and logs: "ok", "err_null", "err_config", "err_catalog", "err_memory",
 * "err_not_initialised", "err_argument", "err_internal"; "unknown" for any other value. Never NULL. */
const char* ssiu_flight_result_name(ssiu_result r);

#ifdef __cplusplus
}
#endif

#endif /* SSIU_FLIGHT_H_ */
