// Fixed-size Eigen aliases used across ssiu (one place, as Ceres' eigen.h).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace ssiu {

using Vec2 = Eigen::Vector2d;
using Vec3 = Eigen::Vector3d;
using Vec4 = Eigen::Vector4d;
using Mat2 = Eigen::Matrix2d;
using Mat3 = Eigen::Matrix3d;
using Mat4 = Eigen::Matrix4d;
using Quat = Eigen::Quaterniond;  // Hamilton; see attitude.h for ssiu's conventions.

constexpr double kPi = 3.14159265358979323846;
constexpr double kDegToRad = kPi / 180.0;
constexpr double kRadToDeg = 180.0 / kPi;
constexpr double kArcsecToRad = kDegToRad / 3600.0;
constexpr double kRadToArcsec = 1.0 / kArcsecToRad;
constexpr double kDphToRadS = kDegToRad / 3600.0;  // gyro rates and biases: deg/h -> rad/s
constexpr double kRadSToDph = 1.0 / kDphToRadS;

}  // namespace ssiu
