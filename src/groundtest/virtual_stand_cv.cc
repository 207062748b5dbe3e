// The renderers of virtual_stand.h (OpenCV blurs and resampling), in the OpenCV edge module
// (core/opencv_edge.h).
#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "core/attitude.h"
#include "core/error.h"
#include "core/rng.h"
#include "groundtest/virtual_stand.h"

namespace ssiu {

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
void AddHole(std::vector<double>* e, int w, int h, double x, double y, double rh, double rd, double sigma,
             double flux) {
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
      const double glow =
          o.stray_glow_e_per_s * std::exp(-0.5 * ((x - gx) * (x - gx) + (y - gy) * (y - gy)) / (sg * sg));
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

std::vector<float> RenderAuxScene(const Mask& m, const PlatePose& pose, const AuxCamera& aux, const PhotoOptions& o,
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
      const int k = static_cast<int>(std::floor((x - t.x0) / t.cell)),
                r = static_cast<int>(std::floor((y - t.y0) / t.cell));
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
    for (int X = 0; X <= W; ++X)
      (*r)[X] = reflectance_at(-0.5 + static_cast<double>(X) / ss, -0.5 + static_cast<double>(Y) / ss);
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
  std::vector<float> out(static_cast<size_t>(w) * h);
  for (int y = 0; y < h; ++y)
    std::copy(img.ptr<float>(y), img.ptr<float>(y) + w, out.begin() + static_cast<size_t>(y) * w);
  return out;
}

}  // namespace ssiu
