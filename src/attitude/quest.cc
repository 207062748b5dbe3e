#include "attitude/quest.h"

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <algorithm>
#include <array>
#include <cmath>

#include "core/error.h"

namespace ssiu {
namespace {

struct Profile {
  Mat3 b = Mat3::Zero();  // B = sum a b r^T (Shuster's attitude profile matrix)
  double a_sum = 0;
};

// The observations are read through `each`, a callable each(f) that calls f(b, r, sigma) for every
// observation in order: a vector of WahbaObservation, an identification's matches, or several heads'
// matches turned to body axes, all without a copy (nothing here allocates).
template <class Each>
Profile MakeProfile(const Each& each, const Mat3& rot_ref) {
  Profile p;
  each([&](const Vec3& b, const Vec3& r, double sigma) {
    const double a = 1.0 / (sigma * sigma);
    p.b += a * b * (rot_ref * r).transpose();
    p.a_sum += a;
  });
  return p;
}

auto EachOf(const std::vector<WahbaObservation>& obs) {
  return [&obs](auto&& f) {
    for (const auto& o : obs) f(o.b_sensor, o.r_inertial, o.sigma_rad);
  };
}

auto EachOf(const Identification& id) {
  return [&id](auto&& f) {
    for (const auto& m : id.matches) f(m.b_sensor, m.r_inertial, m.sigma_rad);
  };
}

// Attitude matrix A (reference -> sensor) of a quaternion [e, q4] in Shuster's convention.
Mat3 ShusterA(const Vec3& e, double q4) {
  Mat3 ex;
  ex << 0, -e[2], e[1], e[2], 0, -e[0], -e[1], e[0], 0;
  return (q4 * q4 - e.squaredNorm()) * Mat3::Identity() + 2 * e * e.transpose() - 2 * q4 * ex;
}

Quat FromSensorToInertial(const Mat3& a_ref_to_sensor) {
  Quat q(Mat3(a_ref_to_sensor.transpose()));
  q.normalize();
  if (q.w() < 0) q.coeffs() = -q.coeffs();
  return q;
}

// One QUEST solve in the (possibly rotated) reference frame. Returns |q4| of the solution (small
// near a 180-degree rotation, where QUEST loses precision) and A (reference -> sensor).
double QuestOnce(const Profile& p, Mat3* a_out) {
  const Mat3& b = p.b;
  const Mat3 s = b + b.transpose();
  const Vec3 z(b(1, 2) - b(2, 1), b(2, 0) - b(0, 2), b(0, 1) - b(1, 0));
  const double sigma = b.trace();
  // adj(S) without inverting S (S may be singular).
  Mat3 adj;
  adj(0, 0) = s(1, 1) * s(2, 2) - s(1, 2) * s(2, 1);
  adj(1, 1) = s(0, 0) * s(2, 2) - s(0, 2) * s(2, 0);
  adj(2, 2) = s(0, 0) * s(1, 1) - s(0, 1) * s(1, 0);
  const double kappa = adj(0, 0) + adj(1, 1) + adj(2, 2);
  const double delta = s.determinant();
  // Characteristic equation of K (Shuster & Oh 1981, eq. 70-71), Newton from lambda0 = sum a_i.
  const double ca = sigma * sigma - kappa;
  const double cb = sigma * sigma + z.squaredNorm();
  const double cc = delta + z.dot(s * z);
  const double cd = z.dot(s * s * z);
  double lambda = p.a_sum;
  for (int i = 0; i < 50; ++i) {
    const double l2 = lambda * lambda;
    const double f = l2 * l2 - (ca + cb) * l2 - cc * lambda + (ca * cb + cc * sigma - cd);
    const double df = 4 * l2 * lambda - 2 * (ca + cb) * lambda - cc;
    const double step = f / df;
    lambda -= step;
    if (std::abs(step) < 1e-15 * p.a_sum) break;
  }
  const double alpha = lambda * lambda - sigma * sigma + kappa;
  const double beta = lambda - sigma;
  const double gamma = (lambda + sigma) * alpha - delta;
  const Vec3 x = (alpha * Mat3::Identity() + beta * s + s * s) * z;
  const double norm = std::sqrt(gamma * gamma + x.squaredNorm());
  *a_out = ShusterA(x / norm, gamma / norm);
  return std::abs(gamma) / norm;
}

template <class Each>
Mat3 QuestCovarianceOf(const Each& each) {
  Mat3 f = Mat3::Zero();
  each([&](const Vec3& b, const Vec3&, double sigma) { f += (Mat3::Identity() - b * b.transpose()) / (sigma * sigma); });
  return f.inverse();
}

template <class Each>
Mat3 AttitudeInformationOf(const Each& each, bool free_scale) {
  // Linearised measurement b_i(theta, e) with the error rotation theta (sensor frame) and a relative
  // focal-length error e: d b_i / d theta = [b_i]x (Shuster 1989), and since a pinhole direction is
  // (t, 1) / |(t, 1)| with tangent-plane coordinates t = pixel offset / f, scaling f by 1 + e moves t
  // by -e t, so d b_i / d e = -(I - b_i b_i^T) (b_x, b_y, 0) (distortion neglected). The marginal
  // information of theta is the Schur complement F_tt - F_te F_te^T / F_ee.
  Mat3 f_tt = Mat3::Zero();
  Vec3 f_te = Vec3::Zero();
  double f_ee = 0;
  each([&](const Vec3& b, const Vec3&, double sigma) {
    const double w = 1.0 / (sigma * sigma);
    const Mat3 perp = Mat3::Identity() - b * b.transpose();
    const Vec3 g = -perp * Vec3(b.x(), b.y(), 0);
    f_tt += w * perp;
    f_te += w * b.cross(g);
    f_ee += w * g.squaredNorm();
  });
  return free_scale && f_ee > 0 ? Mat3(f_tt - f_te * f_te.transpose() / f_ee) : f_tt;
}

void SetSigmas(AttitudeSolution* s) {
  s->sigma_cross_rad = std::sqrt((s->covariance_rad2(0, 0) + s->covariance_rad2(1, 1)) / 2);
  s->sigma_roll_rad = std::sqrt(s->covariance_rad2(2, 2));
}

// QUEST over the n observations of `each`.
template <class Each>
AttitudeSolution SolveQuestOf(const Each& each, size_t n) {
  AttitudeSolution out;
  out.num_observations = static_cast<int>(n);
  if (n < 2) {
    out.status = SolveStatus::kTooFewStars;
    return out;
  }
  // Method of sequential rotations (Shuster & Oh 1981, sec. VI): if q4 is small (rotation near
  // 180 deg), solve with the reference frame turned by pi about x, y or z and undo it.
  Mat3 a;
  const double q4 = QuestOnce(MakeProfile(each, Mat3::Identity()), &a);
  if (q4 < 0.3) {
    // Of the three turned frames, at least one has |q4| >= 1/2; take the best conditioned.
    double best = q4;
    for (int axis = 0; axis < 3; ++axis) {
      Mat3 rot = -Mat3::Identity();
      rot(axis, axis) = 1;  // pi about `axis`
      Mat3 a2;
      const double q4_rot = QuestOnce(MakeProfile(each, rot), &a2);
      if (q4_rot > best) {
        best = q4_rot;
        a = a2 * rot;  // b = A2 (rot r)
      }
    }
  }
  out.status = SolveStatus::kSolved;
  out.q_inertial_from_sensor = FromSensorToInertial(a);
  out.covariance_rad2 = QuestCovarianceOf(each);
  SetSigmas(&out);
  each([&](const Vec3& b, const Vec3& r, double sigma) { out.loss += 0.5 * (b - a * r).squaredNorm() / (sigma * sigma); });
  return out;
}

}  // namespace

Mat3 QuestCovariance(const std::vector<WahbaObservation>& obs) { return QuestCovarianceOf(EachOf(obs)); }

Mat3 AttitudeInformation(const std::vector<WahbaObservation>& obs, bool free_scale) {
  return AttitudeInformationOf(EachOf(obs), free_scale);
}

AttitudeSolution SolveQuest(const std::vector<WahbaObservation>& obs) { return SolveQuestOf(EachOf(obs), obs.size()); }

Quat SolveDavenport(const std::vector<WahbaObservation>& obs) {
  const Profile p = MakeProfile(EachOf(obs), Mat3::Identity());
  const Mat3 s = p.b + p.b.transpose();
  const Vec3 z(p.b(1, 2) - p.b(2, 1), p.b(2, 0) - p.b(0, 2), p.b(0, 1) - p.b(1, 0));
  const double sigma = p.b.trace();
  Mat4 k;
  k.topLeftCorner<3, 3>() = s - sigma * Mat3::Identity();
  k.topRightCorner<3, 1>() = z;
  k.bottomLeftCorner<1, 3>() = z.transpose();
  k(3, 3) = sigma;
  Eigen::SelfAdjointEigenSolver<Mat4> es(k);
  const Vec4 q = es.eigenvectors().col(3);  // eigenvalues ascending
  return FromSensorToInertial(ShusterA(q.head<3>(), q[3]));
}

AttitudeSolution SolveAttitude(const Identification& id) {
  if (id.status != SolveStatus::kSolved) {
    AttitudeSolution out;
    out.status = id.status;
    return out;
  }
  // The matches are read in place (no copy): nothing here allocates.
  AttitudeSolution out = SolveQuestOf(EachOf(id), id.matches.size());
  if (id.focal_length_fitted && out.status == SolveStatus::kSolved) {
    // The focal length was fitted from the same stars: its uncertainty is part of the attitude's.
    out.covariance_rad2 = AttitudeInformationOf(EachOf(id), true).inverse();
    SetSigmas(&out);
  }
  if (id.principal_point_refined && out.status == SolveStatus::kSolved) {
    out.covariance_rad2 += id.principal_point_attitude_cov_rad2;
    SetSigmas(&out);
  }
  return out;
}

const char* MultiHeadOptions::Problem() const {
  if (!(consistency_sigmas > 0 && consistency_sigmas < 1000)) return "consistency_sigmas must be in (0, 1000)";
  if (!(mount_tolerance_arcsec >= 0 && mount_tolerance_arcsec < 36000))
    return "mount_tolerance_arcsec must be in [0, 36000)";
  return nullptr;
}

void MultiHeadOptions::Check() const {
  if (const char* p = Problem()) throw InputError("multi-head options", p);
}

namespace {

// The pairwise test enumerates the subsets of the solved heads: at most this many take part.
constexpr int kMaxFusedHeads = 16;

struct Fusion {
  AttitudeSolution attitude;
  double false_match_probability = 1.0;
  int solved = 0, used = 0;
  size_t stars = 0;
};

// The fusion of SolveMultiHeadChecked over heads.size() == mounts.size() heads and valid options,
// without allocating: per-head results go to head_use[h] and q_per_head[h] where those are given.
Fusion FuseHeads(const std::vector<Identification>& heads, const std::vector<Quat>& q_body_from_sensor,
                 const MultiHeadOptions& o, HeadUse* head_use, Quat* q_per_head) {
  const size_t n = heads.size();
  Fusion out;
  for (size_t h = 0; h < n; ++h) {
    if (head_use) head_use[h] = HeadUse::kOwnStatus;
    if (q_per_head) q_per_head[h] = Quat::Identity();
  }
  // Each solved head's own body attitude and its covariance in body axes: with
  // q_inertial_from_body = q_sensor * conj(mount), a sensor-frame error dtheta_s is R(mount) dtheta_s in body axes.
  struct Solved {
    size_t h;
    Quat q_body;
    Mat3 p_body;
  };
  std::array<Solved, kMaxFusedHeads> solved;
  int ns = 0;  // solved heads (those past kMaxFusedHeads are not kept: no subset is then enumerated)
  for (size_t h = 0; h < n; ++h) {
    if (heads[h].status != SolveStatus::kSolved) continue;
    const AttitudeSolution s = SolveAttitude(heads[h]);
    if (s.status != SolveStatus::kSolved) continue;
    const Quat m = q_body_from_sensor[h].normalized();
    const Mat3 rm = m.toRotationMatrix();
    const Quat q_body = (s.q_inertial_from_sensor * m.conjugate()).normalized();
    if (q_per_head) q_per_head[h] = q_body;
    if (ns < kMaxFusedHeads) solved[static_cast<size_t>(ns)] = {h, q_body, rm * s.covariance_rad2 * rm.transpose()};
    ++ns;
  }
  out.solved = ns;
  const double tol = o.mount_tolerance_arcsec * kArcsecToRad;
  auto agree = [&](int i, int j) {
    Quat d = solved[i].q_body.conjugate() * solved[j].q_body;
    if (d.w() < 0) d.coeffs() = -d.coeffs();
    const Vec3 e = 2 * d.vec();
    const Mat3 s = solved[i].p_body + solved[j].p_body + tol * tol * Mat3::Identity();
    return e.dot(s.inverse() * e) <= o.consistency_sigmas * o.consistency_sigmas;
  };
  // Largest pairwise-consistent subset (at most a few heads: enumerate the subsets).
  unsigned best = 0;
  auto better = [&](unsigned a, unsigned b) {  // is subset a better than b?
    const int ca = __builtin_popcount(a), cb = __builtin_popcount(b);
    if (ca != cb) return ca > cb;
    size_t ma = 0, mb = 0;
    double pa = 0, pb = 0;
    for (int k = 0; k < ns; ++k) {
      const auto& id = heads[solved[k].h];
      if (a >> k & 1u) ma += id.matches.size(), pa += id.false_match_probability;
      if (b >> k & 1u) mb += id.matches.size(), pb += id.false_match_probability;
    }
    if (ma != mb) return ma > mb;
    return pa < pb;
  };
  for (unsigned set = 1; ns <= kMaxFusedHeads && set < (1u << ns); ++set) {
    bool ok = true;
    for (int a = 0; a < ns && ok; ++a)
      for (int b = a + 1; b < ns && ok; ++b)
        if ((set >> a & 1u) && (set >> b & 1u)) ok = agree(a, b);
    if (ok && (best == 0 || better(set, best))) best = set;
  }
  out.false_match_probability = 0;
  bool any_scale = false;
  Mat3 info = Mat3::Zero();  // sum of the heads' information in body axes (each with its own focal length)
  const size_t kept = static_cast<size_t>(std::min(ns, kMaxFusedHeads));
  for (size_t h = 0, k = 0; h < n; ++h) {  // k: index among the kept solved heads
    if (k >= kept || solved[k].h != h) {
      // With more solved heads than kMaxFusedHeads none is fused (best is empty): every solved one,
      // kept or not, is left out as inconsistent.
      if (head_use && ns > kMaxFusedHeads && heads[h].status == SolveStatus::kSolved &&
          SolveAttitude(heads[h]).status == SolveStatus::kSolved)
        head_use[h] = HeadUse::kInconsistent;
      continue;
    }
    const bool in_best = best >> k & 1u;
    ++k;
    if (!in_best) {
      if (head_use) head_use[h] = HeadUse::kInconsistent;
      continue;
    }
    if (head_use) head_use[h] = HeadUse::kUsed;
    ++out.used;
    out.stars += heads[h].matches.size();
    out.false_match_probability += heads[h].false_match_probability;
    any_scale |= heads[h].focal_length_fitted;
    const Mat3 r = q_body_from_sensor[h].normalized().toRotationMatrix();
    const Mat3 f = AttitudeInformationOf(EachOf(heads[h]), heads[h].focal_length_fitted);
    info += r * f * r.transpose();
  }
  out.false_match_probability = std::min(1.0, out.false_match_probability);
  if (out.used == 0 || out.stars < 3) {
    bool any_no_match = false;
    for (const auto& id : heads) any_no_match |= id.status != SolveStatus::kTooFewStars;
    out.attitude.status = any_no_match || heads.empty() ? SolveStatus::kNoMatch : SolveStatus::kTooFewStars;
    out.false_match_probability = 1.0;
    return out;
  }
  // The used heads' matches, turned to body axes, in head order.
  auto each = [&](auto&& f) {
    for (size_t h = 0, k = 0; h < n && k < kept; ++h) {
      if (solved[k].h != h) continue;
      if (best >> k++ & 1u) {
        const Mat3 r = q_body_from_sensor[h].normalized().toRotationMatrix();
        for (const auto& m : heads[h].matches) f(Vec3(r * m.b_sensor), m.r_inertial, m.sigma_rad);
      }
    }
  };
  out.attitude = SolveQuestOf(each, out.stars);
  if (any_scale) {
    out.attitude.covariance_rad2 = info.inverse();
    SetSigmas(&out.attitude);
  }
  return out;
}

void CheckCounts(const std::vector<Identification>& heads, const std::vector<Quat>& q_body_from_sensor) {
  if (heads.size() != q_body_from_sensor.size())
    throw InputError("multi-head", std::to_string(heads.size()) + " heads but " +
                                       std::to_string(q_body_from_sensor.size()) + " mounts");
}

}  // namespace

void SolveMultiHeadChecked(const std::vector<Identification>& heads, const std::vector<Quat>& q_body_from_sensor,
                           const MultiHeadOptions& o, MultiHeadSolution* out, bool diagnostics) {
  const size_t n = heads.size();
  out->head_use.assign(n, HeadUse::kOwnStatus);
  out->q_inertial_from_body_per_head.assign(n, Quat::Identity());
  out->message.clear();
  out->input_error = o.Problem() != nullptr || q_body_from_sensor.size() != n;
  if (out->input_error) {
    out->attitude = AttitudeSolution{};
    out->attitude.status = SolveStatus::kNoMatch;
    out->false_match_probability = 1.0;
    if (diagnostics) {
      out->message = o.Problem() ? std::string("multi-head options: ") + o.Problem()
                                 : std::to_string(n) + " heads but " + std::to_string(q_body_from_sensor.size()) +
                                       " mounts";
    }
    return;
  }
  const Fusion f = FuseHeads(heads, q_body_from_sensor, o, out->head_use.data(), out->q_inertial_from_body_per_head.data());
  out->attitude = f.attitude;
  out->false_match_probability = f.false_match_probability;
  if (!diagnostics) return;
  if (f.used == 0 || f.stars < 3) {
    out->message = "no head solved";
    return;
  }
  out->message =
      std::to_string(f.used) + " of " + std::to_string(n) + " heads fused, " + std::to_string(f.stars) + " stars";
  if (f.used < f.solved)
    out->message +=
        "; " + std::to_string(f.solved - f.used) + " solved head(s) disagree with the others (wrong solve or mount)";
}

MultiHeadSolution SolveMultiHeadChecked(const std::vector<Identification>& heads,
                                        const std::vector<Quat>& q_body_from_sensor, const MultiHeadOptions& o) {
  o.Check();
  CheckCounts(heads, q_body_from_sensor);
  MultiHeadSolution out;
  SolveMultiHeadChecked(heads, q_body_from_sensor, o, &out, true);
  return out;
}

AttitudeSolution SolveMultiHead(const std::vector<Identification>& heads, const std::vector<Quat>& q_body_from_sensor) {
  CheckCounts(heads, q_body_from_sensor);
  return FuseHeads(heads, q_body_from_sensor, MultiHeadOptions{}, nullptr, nullptr).attitude;
}

}  // namespace ssiu
