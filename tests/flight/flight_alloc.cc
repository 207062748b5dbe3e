// The flight core's rule (issue 26, docs/flight.md): after ssiu_flight_init, no call allocates on the
// heap or throws. Counted (operator new, and glibc malloc outside the sanitizer builds) around every
// call of the C interface over a 120 s two-head mission that has the lost-in-space start, a head
// outage (head 2 silent from 30 to 60 s, then lost in space again), a gyro fault (gyro 2 steps by
// 80 deg/h at 30 s: detected and isolated), and bad inputs among them (a NaN sample, a repeated time
// tag, a frame of the wrong size). The answers are checked against the simulator's truth, so the
// calls counted are ones that did their work.
#include <gtest/gtest.h>
#include <sys/mman.h>
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <vector>

#include "core/attitude.h"
#include "core/output.h"
#include "flight/flight_config.h"
#include "flight/flight_print.h"
#include "flight/ssiu_flight.h"
#include "identify/star_catalog.h"
#include "inertial/unit_processor.h"
#include "sim/mission.h"
#include "testing/alloc_count.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

// The handle's memory, 16-byte aligned as ssiu_flight_init asks (std::max_align_t is 8 on 32-bit ARM).
struct alignas(16) Block16 {
  unsigned char bytes[16];
};

constexpr double kOutageStartS = 30, kOutageEndS = 60;

MissionConfig FaultMission() {
  MissionConfig c = DefaultMissionConfig();
  c.duration_s = 120;
  c.frame_rate_hz = 0.5;
  c.seed = 11;
  GyroFault f;
  f.gyro = 2;
  f.t_s = 30;
  f.step_dph = 80;
  c.motion.faults.push_back(f);
  return WithUnitKnowledge(c);
}

struct Counts {
  long calls = 0, allocations = 0, bytes = 0, exceptions = 0;
  void Add(const testing::AllocationCounter& n) {
    ++calls;
    allocations += n.Count();
    bytes += n.Bytes();
    exceptions += n.Exceptions();
  }
};

TEST(FlightAllocation, NoHeapAndNoExceptionAfterInitOverAMissionWithOutageAndFault) {
  const MissionConfig config = FaultMission();
  const MissionData data = SimulateMission(config);
  const std::string blob = SolverCatalogBytes(MakeIdentifierForCamera("", config.heads[0].camera, 0.0).catalog());

  ssiu_flight_config c =
      FlightConfigFor(config.heads, config.unit, config.processor, config.start_utc, config.velocity_kms);
  c.catalog_crc32 = Crc32(blob.data(), blob.size());
  std::vector<Block16> memory(ssiu_flight_memory_bytes(&c) / sizeof(Block16) + 1);
  ssiu_flight* f = nullptr;
  ASSERT_EQ(ssiu_flight_init(&c, blob.data(), blob.size(), memory.data(), memory.size() * sizeof(Block16), &f),
            SSIU_OK)
      << reinterpret_cast<const char*>(memory.data());

  Counts gyro, frames, state;
  long lis_sets = 0, solved_sets = 0, head2_lis_after_outage = 0, partial = 0, refused = 0;
  std::vector<Image16> images(config.heads.size());
  std::vector<ssiu_frame> views(config.heads.size());
  const Image16 wrong_size(100, 100);
  ssiu_frame_report report;
  ssiu_state st;
  const GyroSimulation& g = data.gyro;
  size_t fi = 0;
  auto frames_before = [&](double t) {
    for (; fi < data.frame_t_s.size() && data.frame_t_s[fi] < t - 1e-9; ++fi) {
      const double tf = data.frame_t_s[fi];
      for (size_t h = 0; h < config.heads.size(); ++h) {
        const bool silent = h == 1 && tf >= kOutageStartS && tf < kOutageEndS;
        if (silent) {
          views[h] = ssiu_frame{};
          continue;
        }
        images[h] = SimulateMissionFrame(config, data, testing::Bsc(), static_cast<int>(fi), static_cast<int>(h)).image;
        views[h] = ssiu_frame{images[h].pixels.data(), images[h].width, images[h].height, 0};
      }
      // One frame of the wrong size at 90 s: that head's bad_frame, the other head carries on.
      if (std::abs(tf - 90) < 1e-9) views[0] = ssiu_frame{wrong_size.pixels.data(), wrong_size.width, wrong_size.height, 0};
      testing::AllocationCounter n;
      ASSERT_EQ(ssiu_flight_frames(f, tf, views.data(), static_cast<int32_t>(views.size()), &report), SSIU_OK);
      frames.Add(n);
      if (report.status == SSIU_SOLVE_SOLVED) ++solved_sets;
      for (int h = 0; h < c.n_heads; ++h) {
        if (report.heads[h].status == SSIU_SOLVE_SOLVED && report.heads[h].lost_in_space) {
          ++lis_sets;
          if (h == 1 && tf >= kOutageEndS) ++head2_lis_after_outage;
        }
      }
      if (std::abs(tf - 90) < 1e-9) {
        EXPECT_EQ(report.heads[0].status, SSIU_SOLVE_BAD_FRAME);
      }
    }
  };
  for (size_t k = 0; k < g.t_s.size(); ++k) {
    frames_before(g.t_s[k]);
    double sample[SSIU_FLIGHT_MAX_GYROS];
    for (int i = 0; i < c.n_gyros; ++i) sample[i] = g.gyro_dph[k][i];
    if (k == 2000) sample[3] = std::nan("");  // one output unusable: repaired from the others
    ssiu_gyro_status gs;
    testing::AllocationCounter n;
    ASSERT_EQ(ssiu_flight_gyro(f, g.t_s[k], sample, c.n_gyros, &gs), SSIU_OK);
    if (k == 7000) {  // the same time tag again
      ASSERT_EQ(ssiu_flight_gyro(f, g.t_s[k], sample, c.n_gyros, &gs), SSIU_OK);
    }
    gyro.Add(n);
    partial += gs == SSIU_GYRO_PARTIAL;
    refused += k == 7000 && gs != SSIU_GYRO_ACCEPTED;
    if (k % 100 == 0) {
      testing::AllocationCounter m;
      ASSERT_EQ(ssiu_flight_state(f, &st), SSIU_OK);
      state.Add(m);
    }
  }
  frames_before(1e9);
  testing::AllocationCounter m;
  ASSERT_EQ(ssiu_flight_state(f, &st), SSIU_OK);
  state.Add(m);

  // The mission did what it was meant to: the calls counted are the real work.
  EXPECT_EQ(frames.calls, static_cast<long>(data.frame_t_s.size()));
  EXPECT_GE(solved_sets, frames.calls - 1);
  EXPECT_GE(lis_sets, 3);  // both heads at the start, head 2 after its outage
  EXPECT_GE(head2_lis_after_outage, 1);
  EXPECT_EQ(partial, 1);
  EXPECT_EQ(refused, 1);
  ASSERT_GE(st.n_faults, 1);
  EXPECT_EQ(st.faults[0].gyro, 2);
  EXPECT_EQ(st.gyros_in_use & 2u, 0u);
  EXPECT_EQ(st.valid, 1);
  size_t best = 0;
  for (size_t k = 0; k < g.t_s.size(); ++k)
    if (std::abs(g.t_s[k] - st.t_s) < std::abs(g.t_s[best] - st.t_s)) best = k;
  const double err_arcsec =
      AttitudeErrorRad(Quat(st.q_inertial_from_body[0], st.q_inertial_from_body[1], st.q_inertial_from_body[2],
                            st.q_inertial_from_body[3]),
                       g.q_true[best]) *
      kRadToArcsec;
  EXPECT_LT(err_arcsec, 10.0);

  std::printf("flight calls after init: %ld frame sets (%ld allocations, %ld bytes), %ld gyro samples (%ld, %ld), "
              "%ld state reads (%ld, %ld); exceptions %ld; final error %.2f arcsec\n",
              frames.calls, frames.allocations, frames.bytes, gyro.calls, gyro.allocations, gyro.bytes, state.calls,
              state.allocations, state.bytes, frames.exceptions + gyro.exceptions + state.exceptions, err_arcsec);
  EXPECT_EQ(frames.allocations, 0);
  EXPECT_EQ(gyro.allocations, 0);
  EXPECT_EQ(state.allocations, 0);
  EXPECT_EQ(frames.exceptions + gyro.exceptions + state.exceptions, 0);
  ssiu_flight_shutdown(f);
}

// The catalog blob is searched where it lies (docs/flight.md "Catalog"). Placed in read-only pages,
// as in ROM (a write into it would fault), init takes no heap for it: an init that must copy the same
// bytes (one byte off 8-byte alignment) takes at least 95% of the blob more. Both handles give the
// same statuses, matches and attitudes, frame by frame.
TEST(FlightAllocation, CatalogBlobIsSearchedWhereItLies) {
  MissionConfig config = DefaultMissionConfig();
  config.duration_s = 8;
  config.score_after_s = 0;
  config.frame_rate_hz = 1;
  config.seed = 5;
  config = WithUnitKnowledge(config);
  const MissionData data = SimulateMission(config);
  const std::string blob = SolverCatalogBytes(MakeIdentifierForCamera("", config.heads[0].camera, 0.0).catalog());
  const size_t page = static_cast<size_t>(sysconf(_SC_PAGESIZE)), rom_bytes = (blob.size() + page - 1) / page * page;
  void* rom = mmap(nullptr, rom_bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  ASSERT_NE(rom, MAP_FAILED);
  std::memcpy(rom, blob.data(), blob.size());
  ASSERT_EQ(mprotect(rom, rom_bytes, PROT_READ), 0);
  std::vector<char> shifted(blob.size() + 8);
  char* unaligned = shifted.data() + (8 - reinterpret_cast<uintptr_t>(shifted.data()) % 8) % 8 + 1;
  std::memcpy(unaligned, blob.data(), blob.size());

  ssiu_flight_config c =
      FlightConfigFor(config.heads, config.unit, config.processor, config.start_utc, config.velocity_kms);
  c.catalog_crc32 = Crc32(blob.data(), blob.size());
  const size_t need = ssiu_flight_memory_bytes(&c);
  std::vector<Block16> memory_a(need / sizeof(Block16) + 1), memory_b(need / sizeof(Block16) + 1);
  ssiu_flight *a = nullptr, *b = nullptr;
  testing::AllocationCounter n;
  ASSERT_EQ(ssiu_flight_init(&c, rom, blob.size(), memory_a.data(), memory_a.size() * sizeof(Block16), &a), SSIU_OK)
      << reinterpret_cast<const char*>(memory_a.data());
  const long in_place_bytes = n.Bytes();
  n.Reset();
  ASSERT_EQ(ssiu_flight_init(&c, unaligned, blob.size(), memory_b.data(), memory_b.size() * sizeof(Block16), &b),
            SSIU_OK)
      << reinterpret_cast<const char*>(memory_b.data());
  const long copied_bytes = n.Bytes();
  std::printf("heap at init: blob in place %ld bytes, copied %ld bytes (blob %zu bytes)\n", in_place_bytes,
              copied_bytes, blob.size());
  EXPECT_GT(static_cast<double>(copied_bytes - in_place_bytes), 0.95 * static_cast<double>(blob.size()));

  std::vector<Image16> images(config.heads.size());
  std::vector<ssiu_frame> views(config.heads.size());
  const GyroSimulation& g = data.gyro;
  size_t fi = 0;
  int solved = 0;
  for (size_t k = 0; k < g.t_s.size(); ++k) {
    for (; fi < data.frame_t_s.size() && data.frame_t_s[fi] < g.t_s[k] - 1e-9; ++fi) {
      for (size_t h = 0; h < config.heads.size(); ++h) {
        images[h] = SimulateMissionFrame(config, data, testing::Bsc(), static_cast<int>(fi), static_cast<int>(h)).image;
        views[h] = ssiu_frame{images[h].pixels.data(), images[h].width, images[h].height, 0};
      }
      ssiu_frame_report ra, rb;
      ASSERT_EQ(ssiu_flight_frames(a, data.frame_t_s[fi], views.data(), c.n_heads, &ra), SSIU_OK);
      ASSERT_EQ(ssiu_flight_frames(b, data.frame_t_s[fi], views.data(), c.n_heads, &rb), SSIU_OK);
      EXPECT_EQ(ra.status, rb.status) << fi;
      solved += ra.status == SSIU_SOLVE_SOLVED;
      for (int h = 0; h < c.n_heads; ++h) {
        EXPECT_EQ(ra.heads[h].matches, rb.heads[h].matches) << fi;
        for (int i = 0; i < 4; ++i) EXPECT_EQ(ra.heads[h].q_inertial_from_sensor[i], rb.heads[h].q_inertial_from_sensor[i]);
      }
    }
    double sample[SSIU_FLIGHT_MAX_GYROS];
    for (int i = 0; i < c.n_gyros; ++i) sample[i] = g.gyro_dph[k][i];
    ASSERT_EQ(ssiu_flight_gyro(a, g.t_s[k], sample, c.n_gyros, nullptr), SSIU_OK);
    ASSERT_EQ(ssiu_flight_gyro(b, g.t_s[k], sample, c.n_gyros, nullptr), SSIU_OK);
  }
  EXPECT_GE(fi, 8u);  // the frames before the last gyro sample
  EXPECT_EQ(solved, static_cast<int>(fi));
  ssiu_state sa, sb;
  ASSERT_EQ(ssiu_flight_state(a, &sa), SSIU_OK);
  ASSERT_EQ(ssiu_flight_state(b, &sb), SSIU_OK);
  for (int i = 0; i < 4; ++i) EXPECT_EQ(sa.q_inertial_from_body[i], sb.q_inertial_from_body[i]);
  ssiu_flight_shutdown(a);
  ssiu_flight_shutdown(b);
  munmap(rom, rom_bytes);
}

// The workspaces (detection, identification, the fusion's fault monitors, a head's hot-pixel map:
// nearly all the memory) are placed in the caller's block, whose size ssiu_flight_memory_bytes gives exactly: a block
// 16 bytes short is refused (SSIU_ERR_MEMORY, the handle's text names it) and the heap at init is a small part of what
// the same processor takes when made on the heap. (The C handle gives the C++ processor's answers:
// FlightInterface.SameAnswersAsTheProcessorAndNearTheTruth.)
TEST(FlightAllocation, WorkspacesLiveInTheCallersMemory) {
  MissionConfig config = WithUnitKnowledge(DefaultMissionConfig());
  const std::string blob = SolverCatalogBytes(MakeIdentifierForCamera("", config.heads[0].camera, 0.0).catalog());
  ssiu_flight_config c =
      FlightConfigFor(config.heads, config.unit, config.processor, config.start_utc, config.velocity_kms);
  c.catalog_crc32 = Crc32(blob.data(), blob.size());
  // Head 1 lists known hot pixels: their map (a byte a pixel) is a workspace too, in the block.
  c.heads[0].vignetting = 0.3;
  c.heads[0].n_hot_pixels = 40;
  for (int k = 0; k < 40; ++k) {
    c.heads[0].hot_pixels_xy[k][0] = static_cast<uint16_t>(12 * k + 5);
    c.heads[0].hot_pixels_xy[k][1] = static_cast<uint16_t>(500 - 11 * k);
  }
  const FlightSetup setup = FlightSetupFrom(c);
  const auto id = std::make_shared<const StarIdentifier>(
      ParseSolverCatalog(blob.data(), blob.size(), "blob", /*star_tree=*/false, /*in_place=*/true));
  testing::AllocationCounter n;
  long processor_heap = 0;
  {
    const UnitProcessor p(setup.heads, std::vector<std::shared_ptr<const StarIdentifier>>(setup.heads.size(), id),
                          setup.unit, setup.options);
    processor_heap = n.Bytes();
  }
  const size_t need = ssiu_flight_memory_bytes(&c);
  ASSERT_GT(need, 0u);
  std::vector<Block16> memory(need / sizeof(Block16) + 1);
  ssiu_flight* f = nullptr;
  EXPECT_EQ(ssiu_flight_init(&c, blob.data(), blob.size(), memory.data(), need - 16, &f), SSIU_ERR_MEMORY);
  EXPECT_EQ(f, nullptr);
  EXPECT_NE(std::strstr(reinterpret_cast<const char*>(memory.data()), "memory"), nullptr)
      << reinterpret_cast<const char*>(memory.data());
  n.Reset();
  ASSERT_EQ(ssiu_flight_init(&c, blob.data(), blob.size(), memory.data(), need, &f), SSIU_OK)
      << reinterpret_cast<const char*>(memory.data());
  const long init_heap = n.Bytes();
  std::printf(
      "caller's block %zu bytes; heap at init %ld bytes in %ld allocations; the processor on the heap %ld bytes\n",
      need, init_heap, n.Count(), processor_heap);
  EXPECT_GT(static_cast<double>(need), 0.8 * static_cast<double>(processor_heap));
  EXPECT_LT(static_cast<double>(init_heap), 0.01 * static_cast<double>(processor_heap));
  // It runs: a lost-in-space frame set of a simulated sky solves on both heads.
  const MissionData data = SimulateMission(config);
  std::vector<Image16> images(config.heads.size());
  std::vector<ssiu_frame> views(config.heads.size());
  for (size_t h = 0; h < config.heads.size(); ++h) {
    images[h] = SimulateMissionFrame(config, data, testing::Bsc(), 0, static_cast<int>(h)).image;
    views[h] = ssiu_frame{images[h].pixels.data(), images[h].width, images[h].height, 0};
  }
  ssiu_frame_report r;
  n.Reset();
  ASSERT_EQ(ssiu_flight_frames(f, data.frame_t_s[0], views.data(), c.n_heads, &r), SSIU_OK);
  EXPECT_EQ(n.Count(), 0);
  EXPECT_EQ(r.heads_solved, c.n_heads);
  ssiu_flight_shutdown(f);
}

}  // namespace
}  // namespace ssiu
