// The C interface (ssiu_flight.h) over the unit's processor (inertial/unit_processor.h). The handle
// lives in the caller's memory; nothing crosses the interface but plain structs and statuses (every
// C++ exception stops here and becomes SSIU_ERR_INTERNAL, with the handle unchanged where the call
// failed before it changed anything).
#include "flight/ssiu_flight.h"

#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <new>
#include <optional>
#include <string>
#include <vector>

#include "core/arena.h"
#include "core/output.h"
#include "flight/flight_config.h"
#include "identify/star_catalog.h"
#include "inertial/unit_processor.h"

#ifndef SSIU_VERSION_STRING
#define SSIU_VERSION_STRING "0.1.0"
#endif

namespace {

constexpr uint64_t kMagic = 0x53534955464c5431ULL;  // "SSIUFLT1"
constexpr int32_t kInterfaceVersion = 4;
static_assert(SSIU_UNIT_CAL_OFF == static_cast<int>(ssiu::UnitCalStatus::kOff) &&
                  SSIU_UNIT_CAL_ACCUMULATING == static_cast<int>(ssiu::UnitCalStatus::kAccumulating) &&
                  SSIU_UNIT_CAL_NOT_OBSERVABLE == static_cast<int>(ssiu::UnitCalStatus::kNotObservable) &&
                  SSIU_UNIT_CAL_ESTIMATED == static_cast<int>(ssiu::UnitCalStatus::kEstimated) &&
                  SSIU_UNIT_CAL_APPLIED == static_cast<int>(ssiu::UnitCalStatus::kApplied),
              "ssiu_unit_cal_status follows UnitCalStatus");

void CopyText(const char* text, char* out, size_t bytes) {
  if (bytes == 0) return;
  std::snprintf(out, bytes, "%s", text);
}

void Store(const ssiu::Quat& q_in, double out[4]) {
  const ssiu::Quat q = q_in.normalized();
  const double s = q.w() < 0 ? -1 : 1;
  out[0] = s * q.w(), out[1] = s * q.x(), out[2] = s * q.y(), out[3] = s * q.z();
}

int32_t SolveCode(ssiu::SolveStatus s) {
  switch (s) {
    case ssiu::SolveStatus::kSolved:
      return SSIU_SOLVE_SOLVED;
    case ssiu::SolveStatus::kNoMatch:
      return SSIU_SOLVE_NO_MATCH;
    case ssiu::SolveStatus::kTooFewStars:
      return SSIU_SOLVE_TOO_FEW_STARS;
    case ssiu::SolveStatus::kNoFrame:
      return SSIU_SOLVE_NO_FRAME;
    case ssiu::SolveStatus::kBadFrame:
      return SSIU_SOLVE_BAD_FRAME;
  }
  return SSIU_SOLVE_NO_MATCH;
}

ssiu_gyro_status GyroCode(ssiu::GyroSampleStatus s) {
  using G = ssiu::GyroSampleStatus;
  switch (s) {
    case G::kAccepted:
      return SSIU_GYRO_ACCEPTED;
    case G::kAcceptedPartial:
      return SSIU_GYRO_PARTIAL;
    case G::kAcceptedAfterGap:
      return SSIU_GYRO_ACCEPTED_AFTER_GAP;
    case G::kRejectedNonFinite:
      return SSIU_GYRO_REJECTED_NON_FINITE;
    case G::kRejectedOutOfRange:
      return SSIU_GYRO_REJECTED_OUT_OF_RANGE;
    case G::kRejectedOutOfOrder:
      return SSIU_GYRO_REJECTED_OUT_OF_ORDER;
    case G::kRejectedRepeated:
      return SSIU_GYRO_REJECTED_REPEATED;
    case G::kRejectedBadTime:
      return SSIU_GYRO_REJECTED_BAD_TIME;
    case G::kRejectedWrongSize:
      return SSIU_GYRO_REJECTED_WRONG_SIZE;
    case G::kRejectedTimeJump:
      return SSIU_GYRO_REJECTED_TIME_JUMP;
    case G::kAcceptedTimeReset:
      return SSIU_GYRO_ACCEPTED_TIME_RESET;
  }
  return SSIU_GYRO_REJECTED_BAD_TIME;
}

int32_t UpdateCode(ssiu::UpdateStatus s) {
  using U = ssiu::UpdateStatus;
  switch (s) {
    case U::kAccepted:
      return SSIU_UPDATE_ACCEPTED;
    case U::kInitialised:
      return SSIU_UPDATE_INITIALISED;
    case U::kRejectedGate:
      return SSIU_UPDATE_REJECTED_NIS;
    case U::kRejectedLate:
      return SSIU_UPDATE_REJECTED_LATE;
    case U::kRejectedRepeated:
      return SSIU_UPDATE_REJECTED_REPEATED;
    case U::kRejectedBadInput:
      return SSIU_UPDATE_REJECTED_BAD_INPUT;
    case U::kRejectedTimeJump:
      return SSIU_UPDATE_REJECTED_TIME_JUMP;
  }
  return SSIU_UPDATE_REJECTED_BAD_INPUT;
}

}  // namespace

struct ssiu_flight {
  uint64_t magic = kMagic;  // first: Live() reads it raw
  ssiu_flight_config config{};
  // The workspaces' block: the caller's memory after the handle (declared before the processor, so
  // that it outlives it).
  ssiu::Arena arena;
  std::shared_ptr<const ssiu::StarIdentifier> identifier;
  std::optional<ssiu::UnitProcessor> processor;
  // Made at init and reused, so that the calls allocate nothing.
  std::vector<ssiu::ImageView> views;  // one per head
  ssiu::FrameReport report;
  mutable ssiu::UnitAttitude attitude;
  int64_t gyro_samples = 0, frame_sets = 0, frame_sets_solved = 0;
  char error[256] = {0};

  ssiu_flight(void* block, size_t bytes) : arena(block, bytes) {}
  bool Fail(const char* what) {
    CopyText(what, error, sizeof error);
    return false;
  }
};

// The caller's memory: the handle, then the workspaces' arena (aligned as ssiu::Arena asks).
static constexpr size_t kHandleBytes =
    (sizeof(ssiu_flight) + ssiu::Arena::kBlockAlign - 1) / ssiu::Arena::kBlockAlign * ssiu::Arena::kBlockAlign;

extern "C" {

const char* ssiu_flight_version(void) { return SSIU_VERSION_STRING; }
int32_t ssiu_flight_interface_version(void) { return kInterfaceVersion; }

void ssiu_flight_default_config(ssiu_flight_config* c) {
  if (c == nullptr) return;
  std::memset(c, 0, sizeof *c);
  // Two 512x512 heads of 16.6 deg: head 1 along body +Z, head 2 along body -Y (90 deg about +X),
  // each head's poorly observed roll the other's cross-boresight; the four-FOG unit.
  const ssiu::Camera cam = ssiu::MakeCamera(512, 512, 16.6);
  std::vector<ssiu::OpticalHead> heads(2);
  heads[0].camera = heads[1].camera = cam;
  heads[1].q_body_from_sensor = ssiu::Quat(Eigen::AngleAxisd(M_PI / 2, ssiu::Vec3::UnitX()));
  *c = ssiu::FlightConfigFor(heads, ssiu::DefaultFourFogUnit(), ssiu::UnitProcessorOptions{}, "",
                             ssiu::Vec3::Zero());
}

ssiu_result ssiu_flight_parse_config(const char* text, size_t bytes, ssiu_flight_config* config, char* why,
                                     size_t why_bytes) {
  if (text == nullptr || config == nullptr || (why == nullptr && why_bytes > 0)) return SSIU_ERR_NULL;
  try {
    *config = ssiu::ParseFlightConfigText(std::string(text, bytes), "flight.cfg");
    return SSIU_OK;
  } catch (const std::exception& e) {
    if (why) CopyText(e.what(), why, why_bytes);
    return SSIU_ERR_CONFIG;
  }
}

ssiu_result ssiu_flight_check_config(const ssiu_flight_config* config) {
  if (config == nullptr) return SSIU_ERR_NULL;
  try {
    ssiu::FlightSetupFrom(*config);
    return SSIU_OK;
  } catch (const std::exception&) {
    return SSIU_ERR_CONFIG;
  }
}

size_t ssiu_flight_memory_bytes(const ssiu_flight_config* config) {
  if (config == nullptr) return 0;
  try {
    const ssiu::FlightSetup setup = ssiu::FlightSetupFrom(*config);
    return kHandleBytes + ssiu::UnitProcessor::WorkspaceBytes(setup.heads, setup.unit, setup.options);
  } catch (const std::exception&) {
    return 0;
  }
}

ssiu_result ssiu_flight_init(const ssiu_flight_config* config, const void* catalog_blob, size_t catalog_bytes,
                             void* memory, size_t memory_bytes, ssiu_flight** out) {
  if (out != nullptr) *out = nullptr;
  if (config == nullptr || memory == nullptr || out == nullptr) return SSIU_ERR_NULL;
  // On failure the memory holds the reason as a C string (there is no handle to ask).
  char* why = static_cast<char*>(memory);
  ssiu::FlightSetup setup;
  try {
    setup = ssiu::FlightSetupFrom(*config);
  } catch (const std::exception& e) {
    CopyText(e.what(), why, memory_bytes);
    return SSIU_ERR_CONFIG;
  }
  if (memory_bytes < kHandleBytes || reinterpret_cast<uintptr_t>(memory) % ssiu::Arena::kBlockAlign != 0) {
    CopyText("memory: smaller than ssiu_flight_memory_bytes() or not aligned", why, memory_bytes);
    return SSIU_ERR_MEMORY;
  }
  if (catalog_blob == nullptr || catalog_bytes == 0) {
    CopyText("catalog: no catalog blob", why, memory_bytes);
    return SSIU_ERR_CATALOG;
  }
  // The blob's checksum before a byte of it is parsed: a corrupt blob is refused, never read.
  if (config->catalog_crc32 == 0 || ssiu::Crc32(catalog_blob, catalog_bytes) != config->catalog_crc32) {
    CopyText(config->catalog_crc32 == 0 ? "catalog: catalog_crc32 not given (meta.json catalog_bin_crc32)"
                                        : "catalog: CRC-32 differs from catalog_crc32 (corrupt or another catalog)",
             why, memory_bytes);
    return SSIU_ERR_CATALOG;
  }
  ssiu_flight* f = nullptr;
  try {
    auto id = std::make_shared<const ssiu::StarIdentifier>(
        ssiu::ParseSolverCatalog(catalog_blob, catalog_bytes, "catalog blob", /*star_tree=*/false,
                                 /*in_place=*/true));
    // The catalog must serve every head's field of view (ssiu::kCatalogFovTolerance, as the CLI asks).
    for (const auto& h : setup.heads) {
      const double fov_deg = h.camera.FovMaxRad() * ssiu::kRadToDeg;
      if (std::abs(fov_deg / id->catalog().fov_deg - 1) > ssiu::kCatalogFovTolerance) {
        CopyText("catalog: built for another field of view than a head's", why, memory_bytes);
        return SSIU_ERR_CATALOG;
      }
    }
    f = new (memory) ssiu_flight(static_cast<unsigned char*>(memory) + kHandleBytes, memory_bytes - kHandleBytes);
    f->config = *config;
    f->identifier = id;
    std::vector<std::shared_ptr<const ssiu::StarIdentifier>> ids(setup.heads.size(), id);
    f->processor.emplace(setup.heads, ids, setup.unit, setup.options, &f->arena);
    f->views.resize(setup.heads.size());
    // The reused report and state get their room here (a result per head, the gyros in use), so that
    // the first real calls allocate nothing either.
    f->report.heads.reserve(setup.heads.size());
    f->processor->Attitude(&f->attitude, false);
  } catch (const std::bad_alloc&) {
    // The workspaces did not fit the caller's block (nothing else here is that large).
    if (f != nullptr) f->~ssiu_flight();
    CopyText("memory: smaller than ssiu_flight_memory_bytes()", why, memory_bytes);
    return SSIU_ERR_MEMORY;
  } catch (const std::exception& e) {
    if (f != nullptr) f->~ssiu_flight();
    CopyText((std::string("init: ") + e.what()).c_str(), why, memory_bytes);
    return SSIU_ERR_CATALOG;
  }
  *out = f;
  return SSIU_OK;
}

// A handle's first bytes are its magic, read raw: after shutdown (or in memory never initialised) they
// are not kMagic and no member is touched.
static bool Live(const ssiu_flight* f) {
  if (f == nullptr) return false;
  uint64_t magic = 0;
  std::memcpy(&magic, static_cast<const void*>(f), sizeof magic);
  return magic == kMagic;
}

ssiu_result ssiu_flight_gyro(ssiu_flight* f, double t_s, const double* g_dph, int32_t n, ssiu_gyro_status* status) {
  if (f == nullptr || g_dph == nullptr) return SSIU_ERR_NULL;
  if (!Live(f)) return SSIU_ERR_NOT_INITIALISED;
  if (n != f->config.n_gyros) {
    f->Fail("gyro: n differs from config.n_gyros");
    return SSIU_ERR_ARGUMENT;
  }
  ssiu::GyroVec g(n);  // fixed maximum size: no heap
  for (int i = 0; i < n; ++i) g[i] = g_dph[i];
  ssiu_gyro_status st;
  try {  // nothing on this path throws; should anything, it stops here (the handle stays usable)
    st = GyroCode(f->processor->OnGyroSample(t_s, g));
  } catch (...) {
    f->Fail("gyro: internal failure");
    return SSIU_ERR_INTERNAL;
  }
  ++f->gyro_samples;
  if (status) *status = st;
  return SSIU_OK;
}

ssiu_result ssiu_flight_frames(ssiu_flight* f, double t_s, const ssiu_frame* frames, int32_t n,
                               ssiu_frame_report* report) {
  if (f == nullptr || frames == nullptr) return SSIU_ERR_NULL;
  if (!Live(f)) return SSIU_ERR_NOT_INITIALISED;
  if (n != f->config.n_heads) {
    f->Fail("frames: n differs from config.n_heads");
    return SSIU_ERR_ARGUMENT;
  }
  // The processor checks each view against its camera (a wrong size or stride is that head's
  // bad_frame) and the time tag.
  for (int h = 0; h < n; ++h) {
    const ssiu_frame& in = frames[h];
    ssiu::ImageView& v = f->views[static_cast<size_t>(h)];
    v = ssiu::ImageView{};
    if (in.pixels == nullptr) continue;
    v.width = in.width_px, v.height = in.height_px, v.data = in.pixels;
    v.stride = in.stride_px == 0 ? in.width_px : in.stride_px;
  }
  ++f->frame_sets;
  ssiu::FrameReport& fr = f->report;
  try {
    f->processor->OnFrames(t_s, f->views, &fr);
  } catch (...) {
    f->Fail("frames: internal failure");
    return SSIU_ERR_INTERNAL;
  }
  ssiu_frame_report r;
  std::memset(&r, 0, sizeof r);
  r.t_s = t_s;
  for (int h = 0; h < n && h < static_cast<int>(fr.heads.size()); ++h) {
    const ssiu::HeadResult& hr = fr.heads[static_cast<size_t>(h)];
    ssiu_head_report& o = r.heads[h];
    o.status = SolveCode(hr.status);
    o.lost_in_space = hr.mode == ssiu::SolveMode::kLostInSpace;
    o.detections = hr.detections;
    o.matches = hr.matches;
    o.sigma_cross_arcsec = hr.sigma_cross_arcsec;
    o.sigma_roll_arcsec = hr.sigma_roll_arcsec;
    o.false_match_probability = hr.false_match_probability;
    o.photometric_factor = hr.photometric_factor;
    if (hr.status == ssiu::SolveStatus::kSolved) Store(hr.q_inertial_from_sensor, o.q_inertial_from_sensor);
  }
  r.status = SolveCode(fr.status);
  r.heads_solved = fr.heads_solved;
  r.update_status = SSIU_UPDATE_NONE;
  if (fr.status == ssiu::SolveStatus::kSolved) {
    ++f->frame_sets_solved;
    Store(fr.q_inertial_from_body, r.q_inertial_from_body);
    r.update_status = UpdateCode(fr.update.status);
  }
  r.initialised_filter = fr.initialised_filter;
  r.update_accepted = fr.update.accepted;
  r.nis = fr.update.nis;
  if (report) *report = r;
  return SSIU_OK;
}

ssiu_result ssiu_flight_state(const ssiu_flight* f, ssiu_state* s) {
  if (f == nullptr || s == nullptr) return SSIU_ERR_NULL;
  if (!Live(f)) return SSIU_ERR_NOT_INITIALISED;
  std::memset(s, 0, sizeof *s);
  ssiu::UnitAttitude& a = f->attitude;
  try {
    f->processor->Attitude(&a, false);
  } catch (...) {
    return SSIU_ERR_INTERNAL;
  }
  s->valid = a.valid;
  s->status = static_cast<int32_t>(a.status);
  s->t_s = a.t_s;
  Store(a.q_inertial_from_body, s->q_inertial_from_body);
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) s->covariance_rad2[3 * i + j] = a.covariance_rad2(i, j);
    s->bias_dph[i] = a.bias_dph[i];
    s->bias_sigma_dph[i] = a.bias_sigma_dph[i];
  }
  for (int g : a.gyros_in_use) s->gyros_in_use |= 1u << (g - 1);
  const std::vector<ssiu::FaultEvent>& faults = f->processor->fusion().faults();  // in place: no copy
  s->n_faults = static_cast<int32_t>(faults.size());
  for (size_t k = 0; k < faults.size() && k < SSIU_FLIGHT_MAX_FAULTS; ++k) {
    const ssiu::FaultEvent& e = faults[k];
    s->faults[k] = ssiu_fault{e.gyro, e.t_onset_s, e.t_detect_s, e.t_isolate_s, e.fault_dph};
  }
  s->restart_pending = a.restart_pending;
  s->restarts = static_cast<int32_t>(a.restarts);
  s->gyro_samples = f->gyro_samples;
  s->gyro_rejected = a.gyro_samples_refused;
  s->gyro_partial = a.gyro_samples_partial;
  s->frame_sets = f->frame_sets;
  s->frame_sets_solved = f->frame_sets_solved;
  s->frame_sets_refused = a.frames_refused;
  const ssiu::UnitCalState& uc = a.unit_calibration;
  s->unit_cal_status = static_cast<int32_t>(uc.status);
  s->unit_cal_windows = uc.n_windows;
  for (int g = 0; g < uc.n_gyros && g < SSIU_FLIGHT_MAX_GYROS; ++g) {
    s->scale_factor_ppm[g] = uc.scale_factor_ppm[g];
    s->scale_factor_sigma_ppm[g] = uc.scale_factor_sigma_ppm[g];
    for (int k = 0; k < 2; ++k) {
      s->misalignment_arcsec[g][k] = uc.misalignment_arcsec[g][k];
      s->misalignment_sigma_arcsec[g][k] = uc.misalignment_sigma_arcsec[g][k];
    }
  }
  return SSIU_OK;
}

void ssiu_flight_shutdown(ssiu_flight* f) {
  if (!Live(f)) return;
  f->~ssiu_flight();
  const uint64_t zero = 0;
  std::memcpy(static_cast<void*>(f), &zero, sizeof zero);
}

const char* ssiu_flight_last_error(const ssiu_flight* f) { return Live(f) ? f->error : ""; }

const char* ssiu_flight_result_name(ssiu_result r) {
  switch (r) {
    case SSIU_OK:
      return "ok";
    case SSIU_ERR_NULL:
      return "err_null";
    case SSIU_ERR_CONFIG:
      return "err_config";
    case SSIU_ERR_CATALOG:
      return "err_catalog";
    case SSIU_ERR_MEMORY:
      return "err_memory";
    case SSIU_ERR_NOT_INITIALISED:
      return "err_not_initialised";
    case SSIU_ERR_ARGUMENT:
      return "err_argument";
    case SSIU_ERR_INTERNAL:
      return "err_internal";
  }
  return "unknown";
}

}  // extern "C"
