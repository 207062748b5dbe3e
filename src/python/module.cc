// The Python module `ssiu` (its compiled half, `ssiu._ssiu`): the library's calls with numpy arrays in
// and dicts out, the dicts holding the same fields as the CLI's JSON (docs/python.md).
//
//   import ssiu
//   r = ssiu.solve(frame_u16, {"width": 1024, "height": 1024, "focal_length_px": 3510})
//   r["status"], r["q"], r["matches"][0]["star_id"]
//
// Frames are 2-D uint16 arrays read in place (any row stride), uint8 arrays are widened once; centroid
// lists are N x 2..4 float arrays (x_px, y_px[, flux][, sigma_px]), the columns of a centroid CSV.
// Options are keyword arguments named as the CLI's flags (snake_case); an unknown one is a TypeError
// naming the nearest known name, as an unknown JSON key is bad input everywhere else.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "attitude/star_solver.h"
#include "calibration/allan.h"
#include "calibration/allan_io.h"
#include "core/camera.h"
#include "core/error.h"
#include "core/image.h"
#include "core/json.h"
#include "detect/detect.h"
#include "detect/detect_json.h"
#include "inertial/fuse.h"
#include "inertial/gyro_unit.h"

namespace py = pybind11;

namespace ssiu::python {
namespace {

// ---- JSON <-> Python -------------------------------------------------------------------------------

py::object ToPython(const Json& j) {
  switch (j.type()) {
    case Json::value_t::null:
      return py::none();
    case Json::value_t::boolean:
      return py::bool_(j.get<bool>());
    case Json::value_t::number_integer:
      return py::int_(j.get<long long>());
    case Json::value_t::number_unsigned:
      return py::int_(j.get<unsigned long long>());
    case Json::value_t::number_float:
      return py::float_(j.get<double>());
    case Json::value_t::string:
      return py::str(j.get_ref<const std::string&>());
    case Json::value_t::array: {
      py::list l(j.size());
      for (size_t i = 0; i < j.size(); ++i) l[i] = ToPython(j[i]);
      return std::move(l);
    }
    case Json::value_t::object: {
      py::dict d;
      for (auto it = j.begin(); it != j.end(); ++it) d[py::str(it.key())] = ToPython(it.value());
      return std::move(d);
    }
    default:
      return py::none();
  }
}

// A camera from a dict (the content of camera.json) or a path to camera.json; without a focal length
// only when the field of view is searched (fov_x_deg_if_no_focal > 0, core/camera.h). *extras, when
// given, gets what camera.json says beyond the geometry.
Camera CameraFrom(const py::object& camera, double fov_x_deg_if_no_focal = 0, CameraExtras* extras = nullptr) {
  Json j;
  std::string source = "camera";
  if (py::isinstance<py::str>(camera)) {
    source = camera.cast<std::string>();
    j = ReadJsonFile(source);
  } else if (py::isinstance<py::dict>(camera)) {
    j = Json::parse(py::module_::import("json").attr("dumps")(camera).cast<std::string>());
  } else {
    throw py::type_error("camera must be a dict (camera.json's content) or a path to camera.json");
  }
  const Camera c = CameraFromJson(j, source, fov_x_deg_if_no_focal);
  if (extras) *extras = CameraExtrasFromJson(j, c, source);
  return c;
}

// ---- keyword options -------------------------------------------------------------------------------

// Levenshtein distance, for "did you mean" on a misspelt keyword.
size_t EditDistance(const std::string& a, const std::string& b) {
  std::vector<size_t> prev(b.size() + 1), cur(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) prev[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    cur[0] = i;
    for (size_t j = 1; j <= b.size(); ++j)
      cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1)});
    std::swap(prev, cur);
  }
  return prev[b.size()];
}

// Known keyword options of one call: name -> setter.
using Setters = std::map<std::string, std::function<void(const py::handle&)>>;

void ApplyOptions(const py::kwargs& kwargs, const Setters& setters, const char* call) {
  for (const auto& [k, v] : kwargs) {
    const std::string key = k.cast<std::string>();
    const auto it = setters.find(key);
    if (it == setters.end()) {
      std::string best;
      size_t best_d = 4;  // suggest only a near miss
      for (const auto& [name, _] : setters) {
        const size_t d = EditDistance(key, name);
        if (d < best_d) best_d = d, best = name;
      }
      throw py::type_error(std::string(call) + "(): unknown option '" + key + "'" +
                           (best.empty() ? "" : " (did you mean '" + best + "'?)"));
    }
    it->second(v);
  }
}

template <typename T>
std::function<void(const py::handle&)> Set(T* field) {
  return [field](const py::handle& v) { *field = v.cast<T>(); };
}

// Solver-side options (the flags of `ssiu solve`), shared by Solver, solve() and Tracker.
struct SolverConfig {
  SolveOptions solve;
  std::string catalog;  // directory; "" = the cache
  double mag_max = 0;
  std::string source;
};

Setters SolverSetters(SolverConfig* c) {
  IdentifyOptions& id = c->solve.identify;
  return {{"catalog", Set(&c->catalog)},
          {"mag_max", Set(&c->mag_max)},
          {"source", Set(&c->source)},
          {"fov_tolerance_pct", Set(&id.fov_tolerance_pct)},
          {"fov_range_deg",
           [&id](const py::handle& v) {
             const auto r = v.cast<std::vector<double>>();
             if (r.size() != 2) throw InputError("fov_range_deg", "must be (MIN, MAX) in degrees");
             id.fov_min_deg = r[0], id.fov_max_deg = r[1];
           }},
          {"max_false_prob", Set(&id.max_false_match_prob)},
          {"timeout_ms", Set(&id.timeout_ms)},
          {"max_hypotheses", Set(&id.max_hypotheses)},
          {"max_patterns", Set(&id.max_patterns)},
          {"centroid_sigma_px", Set(&id.centroid_sigma_px)},
          {"systematic_px", Set(&id.systematic_px)},
          {"threshold_sigma", Set(&c->solve.detect.threshold_sigma)},
          {"saturation_adu", Set(&c->solve.detect.saturation_adu)},
          {"psf_sigma_px", Set(&c->solve.detect.psf_sigma_px)},
          {"track_search_radius_px", Set(&c->solve.track_search_radius_px)}};
}

// ---- frames and centroids --------------------------------------------------------------------------

// A frame as an ImageView over the caller's array (uint16, no copy) or over a widened copy (uint8).
struct FrameArg {
  ImageView view;
  Image16 owned;          // only for uint8 input
  py::object keep_alive;  // the numpy array the view points into
  double saturation_adu = 65535;
};

FrameArg FrameFrom(const py::array& a) {
  if (a.ndim() != 2) throw py::value_error("a frame must be a 2-D array (rows, columns)");
  FrameArg f;
  const int h = static_cast<int>(a.shape(0)), w = static_cast<int>(a.shape(1));
  if (w < 16 || h < 16) throw py::value_error("a frame must be at least 16x16 pixels");
  if (a.dtype().is(py::dtype::of<uint16_t>())) {
    if (a.strides(1) != 2 || a.strides(0) % 2 != 0 || a.strides(0) < 2 * w)
      throw py::value_error("a uint16 frame must have contiguous rows (use numpy.ascontiguousarray)");
    f.view = {w, h, a.strides(0) / 2, static_cast<const uint16_t*>(a.data())};
    f.keep_alive = a;
  } else if (a.dtype().is(py::dtype::of<uint8_t>())) {
    f.owned = Image16(w, h);
    auto u = a.unchecked<uint8_t, 2>();
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) f.owned.at(x, y) = u(y, x);
    f.view = f.owned.view();
    f.saturation_adu = 255;
  } else {
    throw py::type_error("a frame must be a uint8 or uint16 array (got " + py::str(a.dtype()).cast<std::string>() +
                         ")");
  }
  return f;
}

std::vector<Centroid> CentroidsFrom(const py::array& arr) {
  const auto a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(arr);
  if (!a || a.ndim() != 2 || a.shape(1) < 2 || a.shape(1) > 4)
    throw py::value_error("centroids must be an N x 2..4 array: x_px, y_px[, flux][, sigma_px]");
  const auto u = a.unchecked<2>();
  std::vector<Centroid> c(static_cast<size_t>(a.shape(0)));
  for (py::ssize_t i = 0; i < a.shape(0); ++i) {
    c[i].x_px = u(i, 0);
    c[i].y_px = u(i, 1);
    if (a.shape(1) > 2) c[i].flux = u(i, 2);
    if (a.shape(1) > 3) c[i].sigma_px = u(i, 3);
    for (py::ssize_t k = 0; k < a.shape(1); ++k)
      if (!std::isfinite(u(i, k))) throw py::value_error("centroids: row " + std::to_string(i) + " is not finite");
    if (c[i].sigma_px < 0) throw py::value_error("centroids: row " + std::to_string(i) + " has a negative sigma_px");
  }
  return c;
}

void CheckFrameMatchesCamera(const ImageView& v, const Camera& cam) {
  if (v.width != cam.width || v.height != cam.height)
    throw py::value_error("the frame is " + std::to_string(v.width) + "x" + std::to_string(v.height) +
                          " but the camera says " + std::to_string(cam.width) + "x" + std::to_string(cam.height));
}

// A float array is a centroid list; an integer array is a frame.
bool IsCentroids(const py::array& a) { return a.dtype().kind() == 'f'; }

// ---- solving ---------------------------------------------------------------------------------------

// A camera with its catalog loaded once: what a worker keeps between frames.
class Solver {
 public:
  Solver(const py::object& camera, const py::kwargs& kwargs) {
    ApplyOptions(kwargs, SolverSetters(&config_), "Solver");
    config_.solve.Check();
    const IdentifyOptions& io = config_.solve.identify;
    CameraExtras extras;  // as `ssiu solve`: known hot pixels repaired, the PSF expected, the vignetting out
    camera_ = CameraFrom(camera, io.FovRange() ? std::sqrt(io.fov_min_deg * io.fov_max_deg) : 0.0, &extras);
    MarkHotPixels(extras.hot_pixels, camera_.width, camera_.height, &hot_);
    UseCameraExtras(extras, &config_.solve);
    id_ = std::make_shared<StarIdentifier>(
        MakeIdentifierFor(config_.catalog, camera_, io, config_.mag_max, config_.source));
  }

  // A frame (uint8/uint16 array or a file path: PNG/TIFF/FITS/JPEG/BMP, or a .csv centroid list) -> solve JSON.
  py::object Solve(const py::object& input) const {
    SolveResult r;
    if (py::isinstance<py::str>(input)) {
      const std::string path = input.cast<std::string>();
      if (EndsWithCsv(path)) {
        const auto c = ReadCentroidsCsv(path);
        py::gil_scoped_release nogil;
        r = SolveCentroids(*id_, c, camera_, config_.solve);
      } else {
        const Frame fr = ReadFrame(path);
        SolveOptions so = config_.solve;
        so.detect.saturation_adu = fr.saturation_adu;
        py::gil_scoped_release nogil;
        r = SolveFrame(*id_, fr.image.view(), camera_, so, &hot_);
      }
    } else {
      const py::array a = py::array::ensure(input);
      if (!a) throw py::type_error("solve() takes a frame array, a centroid array or a file path");
      if (IsCentroids(a)) {
        const auto c = CentroidsFrom(a);
        py::gil_scoped_release nogil;
        r = SolveCentroids(*id_, c, camera_, config_.solve);
      } else {
        const FrameArg f = FrameFrom(a);
        CheckSize(f.view);
        SolveOptions so = config_.solve;
        if (so.detect.saturation_adu == DetectOptions{}.saturation_adu) so.detect.saturation_adu = f.saturation_adu;
        py::gil_scoped_release nogil;
        r = SolveFrame(*id_, f.view, camera_, so, &hot_);
      }
    }
    return ToPython(SolveResultToJson(r));
  }

  const Camera& camera() const { return camera_; }
  const std::shared_ptr<StarIdentifier>& identifier() const { return id_; }
  const SolverConfig& config() const { return config_; }

  void CheckSize(const ImageView& v) const { CheckFrameMatchesCamera(v, camera_); }
  const DefectMap& hot() const { return hot_; }

 private:
  static bool EndsWithCsv(const std::string& p) {
    return p.size() >= 4 && (p.compare(p.size() - 4, 4, ".csv") == 0 || p.compare(p.size() - 4, 4, ".CSV") == 0);
  }
  Camera camera_;
  DefectMap hot_;  // camera.json's known hot pixels (repaired before detection); empty when it lists none
  SolverConfig config_;
  std::shared_ptr<StarIdentifier> id_;
};

class PyTracker {
  // Tracking keeps one focal length (as `ssiu track`): find it once with Solver(fov_range_deg=...)
  // and give the fitted one in the camera.
  static Solver NoFovRange(const py::object& camera, const py::kwargs& kwargs) {
    if (kwargs.contains("fov_range_deg"))
      throw InputError("fov_range_deg",
                       "not for a Tracker: solve once with Solver(fov_range_deg=...) and give the "
                       "fitted focal_length_px in the camera");
    return Solver(camera, kwargs);
  }

 public:
  PyTracker(const py::object& camera, const py::kwargs& kwargs)
      : solver_(NoFovRange(camera, kwargs)),
        tracker_(*solver_.identifier(), solver_.camera(), solver_.config().solve) {}

  py::object Update(const py::object& input, double t_s) {
    const py::array a = py::array::ensure(input);
    if (!a) throw py::type_error("update() takes a frame array or a centroid array");
    std::vector<Centroid> c;
    if (IsCentroids(a)) {
      c = CentroidsFrom(a);
    } else {
      const FrameArg f = FrameFrom(a);
      solver_.CheckSize(f.view);
      DetectOptions d = solver_.config().solve.detect;
      if (d.saturation_adu == DetectOptions{}.saturation_adu) d.saturation_adu = f.saturation_adu;
      py::gil_scoped_release nogil;
      c = CentroidsFromDetections(Detect(f.view, d, &solver_.hot()), solver_.config().solve.detector_sigma_scale);
    }
    SolveResult r;
    {
      py::gil_scoped_release nogil;
      r = tracker_.Update(c, t_s);
    }
    return ToPython(SolveResultToJson(r));
  }
  bool locked() const { return tracker_.locked(); }

 private:
  Solver solver_;  // owns the catalog the tracker refers to
  Tracker tracker_;
};

// ---- detection -------------------------------------------------------------------------------------

py::object DetectPy(const py::object& image, const py::object& camera, const py::kwargs& kwargs) {
  DetectOptions o;
  ApplyOptions(kwargs,
               {{"threshold_sigma", Set(&o.threshold_sigma)},
                {"min_snr", Set(&o.min_snr)},
                {"psf_sigma_px", Set(&o.psf_sigma_px)},
                {"gain_e_per_adu", Set(&o.gain_e_per_adu)},
                {"saturation_adu", Set(&o.saturation_adu)},
                {"max_stars", Set(&o.max_stars)},
                {"reject_hot_pixels", Set(&o.reject_hot_pixels)}},
               "detect");
  Frame fr;
  FrameArg f;
  std::string name = "array";
  if (py::isinstance<py::str>(image)) {
    name = image.cast<std::string>();
    fr = ReadFrame(name);
    f.view = fr.image.view();
    if (!kwargs.contains("saturation_adu")) o.saturation_adu = fr.saturation_adu;
  } else {
    f = FrameFrom(py::array::ensure(image));
    if (!kwargs.contains("saturation_adu")) o.saturation_adu = f.saturation_adu;
  }
  DefectMap hot;  // the camera's known hot pixels, repaired as by `ssiu detect`
  if (!camera.is_none()) {
    CameraExtras extras;
    const Camera cam = CameraFrom(camera, 0, &extras);
    CheckFrameMatchesCamera(f.view, cam);
    if (!kwargs.contains("gain_e_per_adu")) o.gain_e_per_adu = cam.gain_e_per_adu;
    MarkHotPixels(extras.hot_pixels, cam.width, cam.height, &hot);
    UseCameraExtras(extras, &o);  // its psf_sigma_px unless psf_sigma_px is given
  }
  o.Check();
  Detections d;
  {
    py::gil_scoped_release nogil;
    d = Detect(f.view, o, &hot);
  }
  return ToPython(DetectionsToJson(d, name, fr.value_scale, fr.value_offset));
}

// A frame file -> (uint16 array owning the pixels, info dict), without a copy of the pixels.
py::tuple ReadFramePy(const std::string& path) {
  auto fr = std::make_unique<Frame>(ReadFrame(path));
  const py::ssize_t h = fr->image.height, w = fr->image.width;
  py::dict info;
  info["file"] = fr->file;
  info["bit_depth"] = fr->bit_depth;
  info["saturation_adu"] = fr->saturation_adu;
  info["value_scale"] = fr->value_scale;
  info["value_offset"] = fr->value_offset;
  info["grey_conversion"] = fr->grey_conversion;
  uint16_t* data = fr->image.pixels.data();
  py::capsule owner(fr.release(), [](void* p) { delete static_cast<Frame*>(p); });
  py::array_t<uint16_t> a({h, w}, {w * py::ssize_t{2}, py::ssize_t{2}}, data, owner);
  return py::make_tuple(a, info);
}

// ---- inertial and analysis -------------------------------------------------------------------------

py::object FusePy(const std::string& gyro, const std::string& star_tracker, const py::object& unit,
                  const py::kwargs& kwargs) {
  FuseOptions o;
  FuseNoiseGiven noise;
  bool no_fdi = false;
  ApplyOptions(kwargs,
               {{"st_sigma_cross_arcsec", Set(&o.st_sigma_cross_arcsec)},
                {"st_sigma_roll_arcsec", Set(&o.st_sigma_roll_arcsec)},
                {"init_bias_sigma_dph", Set(&o.init_bias_sigma_dph)},
                {"output_every", Set(&o.output_every)},
                {"no_fdi", Set(&no_fdi)},
                {"noise", Set(&noise.noise_file)},
                {"arw_deg_per_sqrt_h", Set(&noise.arw_deg_per_sqrt_h)},
                {"bias_instability_dph", Set(&noise.bias_instability_dph)},
                {"rrw_dph_per_sqrt_h", Set(&noise.rrw_dph_per_sqrt_h)}},
               "fuse");
  o.fdi = !no_fdi;
  noise.init_bias_sigma_given = kwargs.contains("init_bias_sigma_dph");  // checked by FuseOptions::Check
  const GyroLog log = ReadGyroLog(gyro, 0);
  std::string noise_source;
  const GyroUnit u =
      FuseUnitForLog(log, gyro, unit.is_none() ? std::string() : unit.cast<std::string>(), noise, &noise_source);
  const StarTrackerLog st = ReadStarTrackerLog(star_tracker);
  FuseResult r;
  {
    py::gil_scoped_release nogil;
    r = Fuse(log, st, u, o);
  }
  r.noise["source"] = noise_source;
  if (!noise.noise_file.empty()) r.noise["noise_file"] = noise.noise_file;
  py::dict out = ToPython(r.ToJson());
  // The attitude history as arrays (the columns of `ssiu fuse --out`).
  const py::ssize_t n = static_cast<py::ssize_t>(r.samples.size());
  py::array_t<double> t(n), q({n, py::ssize_t{4}}), sigma({n, py::ssize_t{3}}), bias({n, py::ssize_t{3}});
  auto tt = t.mutable_unchecked<1>();
  auto qq = q.mutable_unchecked<2>();
  auto ss = sigma.mutable_unchecked<2>();
  auto bb = bias.mutable_unchecked<2>();
  for (py::ssize_t i = 0; i < n; ++i) {
    const FusedSample& s = r.samples[i];
    tt(i) = s.t_s;
    const Quat qn = s.q_inertial_from_body.w() < 0 ? Quat(-s.q_inertial_from_body.coeffs()) : s.q_inertial_from_body;
    qq(i, 0) = qn.w(), qq(i, 1) = qn.x(), qq(i, 2) = qn.y(), qq(i, 3) = qn.z();
    for (int k = 0; k < 3; ++k) ss(i, k) = s.sigma_rad[k] * kRadToArcsec, bb(i, k) = s.bias_dph[k];
  }
  out["t_s"] = t;
  out["q"] = q;
  out["sigma_arcsec"] = sigma;
  out["bias_samples_dph"] = bias;
  return std::move(out);
}

py::object AllanPy(const py::array_t<double, py::array::c_style | py::array::forcecast>& rate, double sample_rate_hz,
                   const std::string& unit, const py::kwargs& kwargs) {
  AllanOptions ao;
  NoiseFitOptions fo;
  ApplyOptions(kwargs,
               {{"confidence", Set(&ao.confidence)},
                {"points_per_decade", Set(&ao.points_per_decade)},
                {"tau_min_s", Set(&fo.tau_min_s)},
                {"tau_max_s", Set(&fo.tau_max_s)},
                {"model_error", Set(&fo.model_error)},
                {"fit_quantization", Set(&fo.fit_quantization)},
                {"fit_bias_instability", Set(&fo.fit_bias_instability)},
                {"fit_rate_ramp", Set(&fo.fit_rate_ramp)}},
               "allan");
  if (rate.ndim() != 1) throw py::value_error("rate must be a 1-D array");
  if (!(sample_rate_hz > 0) || !std::isfinite(sample_rate_hz)) throw py::value_error("sample_rate_hz must be > 0");
  const double to_rad_s = RateUnitToRadPerS(ParseRateUnit(unit, "unit"));
  std::vector<double> r(static_cast<size_t>(rate.shape(0)));
  const auto u = rate.unchecked<1>();
  for (size_t i = 0; i < r.size(); ++i) {
    if (!std::isfinite(u(i))) throw py::value_error("rate[" + std::to_string(i) + "] is not finite");
    r[i] = u(i) * to_rad_s;
  }
  if (r.size() < ao.min_samples)
    throw py::value_error("too few samples (" + std::to_string(r.size()) + ", need " + std::to_string(ao.min_samples) +
                          ")");
  ao.Check();
  fo.Check();
  AllanCurve curve;
  NoiseFit fit;
  {
    py::gil_scoped_release nogil;
    curve = OverlappingAllanDeviation(r, sample_rate_hz, ao);
    fit = FitNoiseTerms(curve, fo);
  }
  const Json provenance = {{"source", "array"}, {"rate_unit", unit}};
  return ToPython(AllanReportJson(curve, fit, provenance, ao.confidence));
}

}  // namespace
}  // namespace ssiu::python

PYBIND11_MODULE(_ssiu, m) {
  using namespace ssiu::python;
  m.doc() = "ssiu: star-tracker and four-FOG star-inertial unit processing (docs/python.md)";
  py::register_exception<ssiu::InputError>(m, "InputError", PyExc_ValueError);

  py::class_<Solver>(m, "Solver",
                     "A camera with its star catalog loaded once. Keyword options are the flags of `ssiu solve`: "
                     "catalog, fov_tolerance_pct, fov_range_deg=(MIN, MAX) (unknown field of view: the camera may "
                     "lack a focal length), max_false_prob, max_hypotheses, max_patterns (the work budget), timeout_ms, centroid_sigma_px, systematic_px, "
                     "threshold_sigma, mag_max, source, saturation_adu, psf_sigma_px")
      .def(py::init<const py::object&, const py::kwargs&>(), py::arg("camera"))
      .def("solve", &Solver::Solve, py::arg("image_or_centroids"),
           "Lost-in-space solve of a frame (2-D uint8/uint16 array or file path) or a centroid list "
           "(N x 2..4 float array or .csv path): a dict with the fields of `ssiu solve --json`");
  py::class_<PyTracker>(m, "Tracker", "Lost in space on the first frame, then tracking (as `ssiu track`)")
      .def(py::init<const py::object&, const py::kwargs&>(), py::arg("camera"))
      .def("update", &PyTracker::Update, py::arg("image_or_centroids"), py::arg("t_s"))
      .def_property_readonly("locked", &PyTracker::locked);
  m.def("read_frame", &ReadFramePy, py::arg("path"),
        "A PNG/TIFF/FITS/JPEG/BMP frame as (uint16 array, info dict with bit_depth, saturation_adu, value_scale, ...)");
  m.def("detect", &DetectPy, py::arg("image"), py::arg("camera") = py::none(),
        "Stars, background, noise and rejected objects of a frame: the fields of `ssiu detect --json`");
  m.def("fuse", &FusePy, py::arg("gyro"), py::arg("star_tracker"), py::arg("unit") = py::none(),
        "Star-inertial fusion of a gyro log and a star-tracker log (CSV paths): the fields of `ssiu fuse --json` "
        "plus arrays t_s, q, sigma_arcsec, bias_samples_dph. Options as the CLI's flags: noise (an `ssiu allan "
        "--json` file), arw_deg_per_sqrt_h, bias_instability_dph, rrw_dph_per_sqrt_h, init_bias_sigma_dph, "
        "st_sigma_cross_arcsec, st_sigma_roll_arcsec, output_every, no_fdi");
  m.def("allan", &AllanPy, py::arg("rate"), py::arg("sample_rate_hz"), py::arg("unit") = "deg/h",
        "Overlapping Allan deviation and IEEE 952 noise terms of a rate array: the fields of `ssiu allan --json`");
}
