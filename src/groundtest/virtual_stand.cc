#include "groundtest/virtual_stand.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "core/attitude.h"
#include "core/error.h"
#include "core/rng.h"

namespace ssiu {

void TrackerViewOptions::Check() const {
  detector.Check();
  if (!(stray_gradient >= 0 && stray_gradient < 1)) throw InputError("tracker view", "stray_gradient must be in [0, 1)");
  if (!(stray_glow_e_per_s >= 0)) throw InputError("tracker view", "stray_glow_e_per_s must be >= 0");
}

void PhotoOptions::Check() const {
  if (!(noise_dn >= 0) || !(blur_px >= 0) || supersample < 1 || supersample > 4)
    throw InputError("photo options", "noise_dn, blur_px >= 0 and supersample in 1..4");
}

void StandSimOptions::Check() const {
  if (positions < 1 || positions > 10000) throw InputError("stand options", "positions must be in 1..10000");
  if (!(step_s > 0)) throw InputError("stand options", "step_s must be > 0");
  if (!(max_angle_deg >= 0 && max_angle_deg < 10)) throw InputError("stand options", "max_angle_deg must be in [0, 10)");
  if (!misalignment_arcmin.allFinite() || misalignment_arcmin.norm() > 600)
    throw InputError("stand options", "misalignment_arcmin must be finite and below 10 deg");
  if (!(encoder_sigma_arcsec >= 0)) throw InputError("stand options", "encoder_sigma_arcsec must be >= 0");
  // The plate sits in a holder: a shift of 10 mm or a turn of 10 deg is a setup error (and NaN gave
  // a NaN plate pose and pictures of nothing, exit 0).
  if (!(std::abs(plate_shift_mm) <= 10)) throw InputError("stand options", "plate_shift_mm must be within +-10 mm");
  if (!(std::abs(plate_turn_deg) <= 10)) throw InputError("stand options", "plate_turn_deg must be within +-10 deg");
  view.Check();
  photo.Check();
}

namespace {

constexpr double kMaxHoleRadiusPx = 100;  // image of one mask hole at the tracker

// Area of the intersection of two disks of radii a, b with centres d apart.
double DiskOverlap(double d, double a, double b) {
  if (d >= a + b) return 0;
  if (d <= std::abs(a - b)) return kPi * std::min(a, b) * std::min(a, b);
  const double ca = std::clamp((d * d + a * a - b * b) / (2 * d * a), -1.0, 1.0);
  const double cb = std::clamp((d * d + b * b - a * a) / (2 * d * b), -1.0, 1.0);
  const double k = (-d + a + b) * (d + a - b) * (d - a + b) * (d + a + b);
  return a * a * std::acos(ca) + b * b * std::acos(cb) - 0.5 * std::sqrt(std::max(0.0, k));
}

// Adds a hole image (disk of radius rh convolved with the defocus disk rd and a Gaussian sigma) of
// total `flux` electrons to `e`, integrated over pixels by supersampling.
void AddHole(std::vector<double>* e, int w, int h, double x, double y, double rh, double rd, double sigma, double flux) {
  constexpr int kSs = 5;
  rh = std::max(rh, 0.02), rd = std::max(rd, 0.02);
  const int rad = static_cast<int>(std::ceil(rh + rd + 4 * sigma + 2));
  const int x0 = static_cast<int>(std::floor(x)) - rad, y0 = static_cast<int>(std::floor(y)) - rad;
  const int n = 2 * rad + 1, ns = n * kSs;
  cv::Mat sub(ns, ns, CV_64F, cv::Scalar(0));
  for (int j = 0; j < ns; ++j)
    for (int i = 0; i < ns; ++i) {
      // Sub-sample centre in pixel coordinates (pixel centres at integers).
      const double px = x0 - 0.5 + (i + 0.5) / kSs, py = y0 - 0.5 + (j + 0.5) / kSs;
      sub.at<double>(j, i) = DiskOverlap(std::hypot(px - x, py - y), rh, rd);
    }
  if (sigma > 0) cv::GaussianBlur(sub, sub, cv::Size(0, 0), sigma * kSs, sigma * kSs, cv::BORDER_CONSTANT);
  const double total = cv::sum(sub)[0];
  if (!(total > 0)) return;
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const int X = x0 + i, Y = y0 + j;
      if (X < 0 || Y < 0 || X >= w || Y >= h) continue;
      const double s = cv::sum(sub(cv::Rect(i * kSs, j * kSs, kSs, kSs)))[0];
      (*e)[static_cast<size_t>(Y) * w + X] += flux * s / total;
    }
}

}  // namespace

Image16 RenderTrackerView(const Mask& m, const PlatePose& pose, const Quat& q_c_from_s, const TrackerViewOptions& o,
                          uint64_t seed, std::vector<ViewStar>* stars_in_view) {
  o.Check();
  const Camera& cam = m.camera;
  const FrameSimOptions& d = o.detector;
  const int w = cam.width, h = cam.height;
  std::vector<double> e(static_cast<size_t>(w) * h, 0.0);
  // Stray light: a linear gradient plus a broad glow, on top of the uniform background and dark.
  const double sg = std::min(w, h) / 3.0;
  const double gx = w / 2.0 * (1 + o.glow_x_frac), gy = h / 2.0 * (1 + o.glow_y_frac);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const double u = (x - w / 2.0) / (w / 2.0);
      const double glow = o.stray_glow_e_per_s * std::exp(-0.5 * ((x - gx) * (x - gx) + (y - gy) * (y - gy)) / (sg * sg));
      e[static_cast<size_t>(y) * w + x] =
          d.exposure_s * (d.background_e_per_s * (1 + o.stray_gradient * u) + glow + d.dark_current_e_per_s);
    }
  const Quat q_s_from_c = q_c_from_s.conjugate();
  for (const auto& hole : m.holes) {
    const Vec3 dir_s = q_s_from_c * ApparentDirection(m, pose, hole.x_mm, hole.y_mm);
    const auto px = cam.Project(dir_s);
    if (!px || !cam.InImage(*px, -10)) continue;
    ViewStar vs;
    vs.star_id = hole.star_id;
    vs.x_px = px->x(), vs.y_px = px->y();
    vs.radius_px = cam.FocalMeanPx() * hole.diameter_mm / 2 / m.collimator_focal_mm;
    // Holes are graded over a few pixel footprints; an absurd diameter (1e9 mm overflowed AddHole's
    // int window size) is refused. At 100 px the supersampled window is already ~100 MB.
    if (!(vs.radius_px <= kMaxHoleRadiusPx)) {
      std::ostringstream msg;
      msg << "hole of HR " << hole.star_id << ": diameter_mm " << hole.diameter_mm << " images to a radius of "
          << vs.radius_px << " px at the tracker (at most " << kMaxHoleRadiusPx << " px)";
      throw InputError("mask", msg.str());
    }
    vs.flux_e = d.mag0_flux_e_per_s * d.exposure_s * std::pow(10.0, -0.4 * hole.mag_effective);
    AddHole(&e, w, h, vs.x_px, vs.y_px, vs.radius_px, d.defocus_radius_px, d.psf_sigma_px, vs.flux_e);
    if (stars_in_view && cam.InImage(*px)) stars_in_view->push_back(vs);
  }
  Rng rng(seed * 2654435761ULL + 17);
  Image16 img(w, h);
  const double max_adu = std::pow(2.0, d.bit_depth) - 1;
  for (size_t i = 0; i < e.size(); ++i) {
    double q = std::min(d.shot_noise ? rng.Poisson(e[i]) : e[i], d.full_well_e);
    q += d.read_noise_e * rng.Normal();
    const double adu = std::round(d.bias_adu + q / d.gain_e_per_adu);
    img.pixels[i] = static_cast<uint16_t>(std::clamp(adu, 0.0, max_adu));
  }
  return img;
}

Json AuxCameraToJson(const AuxCamera& a) {
  Json r = Json::array();
  for (int i = 0; i < 3; ++i) r.push_back({a.r_aux_from_c(i, 0), a.r_aux_from_c(i, 1), a.r_aux_from_c(i, 2)});
  return {{"camera", CameraToJson(a.camera)}, {"r_aux_from_c", r}, {"t_aux_mm", {a.t_aux_mm.x(), a.t_aux_mm.y(), a.t_aux_mm.z()}}};
}

AuxCamera AuxCameraFromJson(const Json& j, const std::string& src) {
  AuxCamera a;
  if (!j.is_object() || !j.contains("camera")) throw InputError(src, "camera: missing (aux camera file)");
  CheckKeys(j, {"camera", "r_aux_from_c", "t_aux_mm"}, src);
  a.camera = CameraFromJson(j["camera"], src + ": camera");
  if (!j.contains("r_aux_from_c") || !j["r_aux_from_c"].is_array() || j["r_aux_from_c"].size() != 3)
    throw InputError(src, "r_aux_from_c: missing or not a 3x3 matrix");
  for (int i = 0; i < 3; ++i) {
    const Json& row = j["r_aux_from_c"][i];
    if (!row.is_array() || row.size() != 3) throw InputError(src, "r_aux_from_c: not a 3x3 matrix");
    for (int k = 0; k < 3; ++k) {
      if (!row[k].is_number()) throw InputError(src, "r_aux_from_c: must hold numbers");
      a.r_aux_from_c(i, k) = row[k];
    }
  }
  if ((a.r_aux_from_c * a.r_aux_from_c.transpose() - Mat3::Identity()).norm() > 1e-6 || a.r_aux_from_c.determinant() < 0)
    throw InputError(src, "r_aux_from_c: not a rotation matrix");
  if (!j.contains("t_aux_mm") || !j["t_aux_mm"].is_array() || j["t_aux_mm"].size() != 3)
    throw InputError(src, "t_aux_mm: missing or not [x,y,z]");
  for (int k = 0; k < 3; ++k) {
    if (!j["t_aux_mm"][k].is_number()) throw InputError(src, "t_aux_mm: must hold numbers");
    a.t_aux_mm(k) = j["t_aux_mm"][k];
  }
  return a;
}

AuxCamera LoadAuxCamera(const std::string& path) { return AuxCameraFromJson(ReadJsonFile(path), path); }

std::vector<uint8_t> RenderAuxPhoto(const Mask& m, const PlatePose& pose, const AuxCamera& aux, const PhotoOptions& o,
                                    uint64_t seed) {
  o.Check();
  const std::string family = o.tag_family.empty() ? m.tag_family : o.tag_family;
  struct TagTex {
    double x0, y0, cell;
    int n;
    std::vector<uint8_t> p;
  };
  std::vector<TagTex> tex;
  if (!o.hide_tags) {
    for (const auto& t : m.tags) {
      TagTex tt;
      tt.p = TagPattern(family, t.id, &tt.n);
      // Keep the black square at the mask's size whatever family is drawn.
      const int border = family == "tag36h11" ? 8 : (family == "tag25h9" ? 7 : (family == "tag16h5" ? 6 : 5));
      tt.cell = t.size_mm / border;
      tt.x0 = t.x_mm - tt.n * tt.cell / 2, tt.y0 = t.y_mm - tt.n * tt.cell / 2;
      tex.push_back(std::move(tt));
    }
  }
  // Reflectance of a plate point: dark grey anodised plate, tags black/white, background darker.
  auto reflectance = [&](double x, double y) {
    if (std::abs(x) > m.plate_half_mm || std::abs(y) > m.plate_half_mm) return 0.05;
    if (std::abs(x) < m.field_half_x_mm && std::abs(y) < m.field_half_y_mm) return 0.25;  // no tag in the star field
    for (const auto& t : tex) {
      const int k = static_cast<int>(std::floor((x - t.x0) / t.cell)), r = static_cast<int>(std::floor((y - t.y0) / t.cell));
      if (k >= 0 && r >= 0 && k < t.n && r < t.n) return t.p[static_cast<size_t>(r) * t.n + k] > 127 ? 0.9 : 0.06;
    }
    return 0.25;
  };
  const Mat3 r_ap = aux.r_aux_from_c * pose.r_c_from_p;
  const Vec3 t_ap = aux.r_aux_from_c * pose.t_c_mm + aux.t_aux_mm;
  const Mat3 r_pa = r_ap.transpose();
  const Vec3 origin_p = -(r_pa * t_ap);
  const int w = aux.camera.width, h = aux.camera.height, ss = o.supersample;
  const bool pinhole = aux.camera.distortion.IsZero();
  const double fx = aux.camera.focal_length_px, fy = aux.camera.FocalYPx();
  auto reflectance_at = [&](double px_x, double px_y) {
    // Pinhole fast path (Unproject iterates the distortion inverse).
    const Vec3 ray = pinhole ? Vec3((px_x - aux.camera.cx_px) / fx, (px_y - aux.camera.cy_px) / fy, 1.0)
                             : aux.camera.Unproject(Vec2(px_x, px_y));
    const Vec3 dir = r_pa * ray;
    if (dir.z() * -origin_p.z() <= 0) return 0.05;
    const double s = -origin_p.z() / dir.z();
    return reflectance(origin_p.x() + s * dir.x(), origin_p.y() + s * dir.y());
  };
  // A camera blurs the scene optically and then integrates it over each pixel: the edge profile is
  // (Gaussian * pixel box), the same at every sub-pixel position of the edge. Blurring an image that
  // is already integrated over whole pixels would not be (its response to an edge is piecewise linear
  // in the edge position, with kinks at the pixel borders), and that pixel-phase error would show in
  // the fiducial corners. So the scene is rendered at ss x the resolution, blurred there, and
  // box-averaged down. A sub-pixel whose four corners agree lies in one region (tag cells and the plate
  // are much larger); one crossed by an edge is integrated with 4 x 4 stratified jittered samples
  // (a regular sub-grid would quantise the edge position to its step).
  const int W = w * ss, H = h * ss;
  cv::Mat hi(H, W, CV_32F);
  Rng jitter(seed * 31 + 7);
  std::vector<double> row0(static_cast<size_t>(W) + 1), row1(row0.size());
  auto corner_row = [&](int Y, std::vector<double>* r) {
    for (int X = 0; X <= W; ++X) (*r)[X] = reflectance_at(-0.5 + static_cast<double>(X) / ss, -0.5 + static_cast<double>(Y) / ss);
  };
  corner_row(0, &row0);
  constexpr int kEdgeSamples = 4;
  for (int Y = 0; Y < H; ++Y) {
    corner_row(Y + 1, &row1);
    float* out = hi.ptr<float>(Y);
    for (int X = 0; X < W; ++X) {
      double v = row0[X];
      if (row0[X + 1] != v || row1[X] != v || row1[X + 1] != v) {
        double acc = 0;
        for (int j = 0; j < kEdgeSamples; ++j)
          for (int i = 0; i < kEdgeSamples; ++i)
            acc += reflectance_at(-0.5 + (X + (i + jitter.Uniform()) / kEdgeSamples) / ss,
                                  -0.5 + (Y + (j + jitter.Uniform()) / kEdgeSamples) / ss);
        v = acc / (kEdgeSamples * kEdgeSamples);
      }
      out[X] = static_cast<float>(15 + 220 * v);
    }
    std::swap(row0, row1);
  }
  if (o.blur_px > 0) cv::GaussianBlur(hi, hi, cv::Size(0, 0), o.blur_px * ss, o.blur_px * ss, cv::BORDER_REPLICATE);
  cv::Mat img;
  cv::resize(hi, img, cv::Size(w, h), 0, 0, cv::INTER_AREA);  // exact box average for an integer factor
  Rng rng(seed * 6364136223846793005ULL + 3);
  std::vector<uint8_t> out(static_cast<size_t>(w) * h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      out[static_cast<size_t>(y) * w + x] =
          static_cast<uint8_t>(std::clamp(std::round(img.at<float>(y, x) + o.noise_dn * rng.Normal()), 0.0, 255.0));
  return out;
}

StandSimulation SimulateStand(const Mask& m, const StandSimOptions& o, uint64_t seed) {
  o.Check();
  Rng rng(seed * 1000003 + 11);
  StandSimulation s;
  s.q_mis = QuatFromRotationVector(o.misalignment_arcmin * (kDegToRad / 60.0));
  s.plate.t_c_mm = Vec3(o.plate_shift_mm, -0.6 * o.plate_shift_mm, 0);
  s.plate.r_c_from_p = Eigen::AngleAxisd(o.plate_turn_deg * kDegToRad, Vec3::UnitZ()).toRotationMatrix();
  s.q_c_from_m = MaskRotation(m, s.plate);
  const double enc = o.encoder_sigma_arcsec / 3600.0;
  for (int i = 0; i < o.positions; ++i) {
    StandPicture p;
    p.t_s = i * o.step_s;
    if (i > 0) {  // the first picture at the stand's zero
      p.az_deg = rng.Uniform(-o.max_angle_deg, o.max_angle_deg);
      p.el_deg = rng.Uniform(-o.max_angle_deg, o.max_angle_deg);
      p.rot_deg = rng.Uniform(-3 * o.max_angle_deg, 3 * o.max_angle_deg);
    }
    p.enc_az_deg = p.az_deg + enc * rng.Normal();
    p.enc_el_deg = p.el_deg + enc * rng.Normal();
    p.enc_rot_deg = p.rot_deg + enc * rng.Normal();
    p.q_c_from_s = StandRotation(p.az_deg * kDegToRad, p.el_deg * kDegToRad, p.rot_deg * kDegToRad) * s.q_mis;
    p.q_true = (m.q_design * s.q_c_from_m.conjugate() * p.q_c_from_s).normalized();
    p.frame = RenderTrackerView(m, s.plate, p.q_c_from_s, o.view, seed * 7919 + i, &p.stars);
    p.photo = RenderAuxPhoto(m, s.plate, o.aux, o.photo, seed * 104729 + i);
    s.pictures.push_back(std::move(p));
  }
  return s;
}

Json StandSimulation::TruthJson(const Mask& m) const {
  Json j;
  const Vec3 mis = RotationVector(q_mis) * (kRadToDeg * 60.0);
  j["misalignment_arcmin"] = {mis.x(), mis.y(), mis.z()};
  const auto qm = ToWxyz(q_mis);
  j["q_mis"] = {qm[0], qm[1], qm[2], qm[3]};
  j["plate_t_c_mm"] = {plate.t_c_mm.x(), plate.t_c_mm.y(), plate.t_c_mm.z()};
  const Vec3 pr = RotationVector(Quat(plate.r_c_from_p)) * kRadToDeg;
  j["plate_rotation_deg"] = {pr.x(), pr.y(), pr.z()};
  const Vec3 cm = RotationVector(q_c_from_m) * kRadToArcsec;
  j["mask_rotation_arcsec"] = {cm.x(), cm.y(), cm.z()};
  Json pics = Json::array();
  for (const auto& p : pictures) {
    const auto q = ToWxyz(p.q_true);
    pics.push_back({{"t_s", p.t_s}, {"az_deg", p.az_deg}, {"el_deg", p.el_deg}, {"rot_deg", p.rot_deg},
                    {"q_true", {q[0], q[1], q[2], q[3]}}, {"stars_in_view", p.stars.size()}});
  }
  j["pictures"] = pics;
  j["design"] = {{"ra_deg", m.ra_deg}, {"dec_deg", m.dec_deg}, {"roll_deg", m.roll_deg}};
  return j;
}

}  // namespace ssiu
