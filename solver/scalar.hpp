// Scalar-type helpers so that physics templates run on double, on ceres::Jet (forward-mode
// automatic differentiation, used for every Jacobian in kneedyn) and on long double (x87
// 80-bit, 64-bit mantissa: the extended-precision references, benchmarks/extended_reference.hpp).
#pragma once

#include <ceres/jet.h>

#include <Eigen/Dense>
#include <type_traits>

// Model data are double; long double expressions mix them in (products, sums) and get
// long double, as Eigen's Jet traits do for ceres::Jet.
namespace Eigen {
template <typename BinaryOp>
struct ScalarBinaryOpTraits<long double, double, BinaryOp> {
  typedef long double ReturnType;
};
template <typename BinaryOp>
struct ScalarBinaryOpTraits<double, long double, BinaryOp> {
  typedef long double ReturnType;
};
}  // namespace Eigen

namespace kneedyn {

inline double ScalarPart(double x) { return x; }
inline double ScalarPart(long double x) { return static_cast<double>(x); }
template <typename T, int N>
double ScalarPart(const ceres::Jet<T, N>& x) {
  return ScalarPart(x.a);
}

// double or a derivative over double (a Jet; TimeDual, time_dual.hpp): the scalars whose
// contact points and patella come from the double solve lifted by the implicit-function
// theorem; wider scalars (the extended-precision references) are refined in their own type
// (surface_wide.hpp, patella_extended.hpp).
/// \cond INTERNAL
template <typename T>
struct IsDoubleOrJet : std::is_same<T, double> {};
template <int N>
struct IsDoubleOrJet<ceres::Jet<double, N>> : std::true_type {};
/// \endcond

// Order of the derivatives a scalar carries: 0 (double, long double), 1 (ceres::Jet over
// double); TimeDual adds one (time_dual.hpp). The surface charts' lift is exact to this
// order (height_field.hpp: EvaluateChart).
/// \cond INTERNAL
template <typename T>
struct DerivativeOrder : std::integral_constant<int, 0> {};
template <typename T, int N>
struct DerivativeOrder<ceres::Jet<T, N>> : std::integral_constant<int, 1 + DerivativeOrder<T>::value> {};
/// \endcond

template <typename T>
using Vector3 = Eigen::Matrix<T, 3, 1>;
template <typename T>
using Matrix3 = Eigen::Matrix<T, 3, 3>;
template <typename T>
using Vector6 = Eigen::Matrix<T, 6, 1>;

using Vector3d = Eigen::Vector3d;
using Matrix3d = Eigen::Matrix3d;
using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;
using VectorXd = Eigen::VectorXd;
using MatrixXd = Eigen::MatrixXd;

// Largest unknown count any formulation differentiates with Jets (22 for the chapter's
// two-point DAE; Newmark with contact coordinates is 6 + 5*2 = 16).
constexpr int kMaxJetSize = 24;
using JetD = ceres::Jet<double, kMaxJetSize>;

}  // namespace kneedyn
