#include "identify/wahba_svd.h"

#include <Eigen/SVD>

namespace ssiu {

Quat SolveWahbaSvd(const std::vector<VectorPair>& pairs) { return SolveWahbaSvd(pairs.data(), pairs.size()); }

Quat SolveWahbaSvd(const VectorPair* pairs, size_t n) {
  // B = sum w r b^T; R = U diag(1, 1, det U det V) V^T maximises tr(R^T B) (Markley 1988, eq. 9-11).
  Mat3 b = Mat3::Zero();
  for (size_t i = 0; i < n; ++i) b += pairs[i].weight * pairs[i].r_inertial * pairs[i].b_sensor.transpose();
  Eigen::JacobiSVD<Mat3> svd(b, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Mat3& u = svd.matrixU();
  const Mat3& v = svd.matrixV();
  Vec3 d(1, 1, u.determinant() * v.determinant());
  const Mat3 r = u * d.asDiagonal() * v.transpose();
  Quat q(r);
  q.normalize();
  if (q.w() < 0) q.coeffs() = -q.coeffs();
  return q;
}

}  // namespace ssiu
