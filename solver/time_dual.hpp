// A dual number over a scalar S (double or ceres::Jet): x = a + ε d with ε² = 0, where ε
// is one direction of motion (the time along q(t) = q + t q̇). TimeDual<JetD> carries the
// mixed second derivatives ∂²/∂x∂t that ceres::Jet cannot nest (Jet<Jet<…>> has no
// constructor from double, which the templated physics uses throughout): the derivative of
// the contact rate term κ = (dG/dt) ν (contact_kinematics.hpp) with respect to (q, q̇), for
// the exact Jacobian of the hidden-constraint solve (ConstrainedAccelerationJacobian).
// Arithmetic with double on either side, and sqrt, sin, cos, found by argument-dependent
// lookup as the templates call them (`using std::sqrt; sqrt(x)`).
#pragma once

#include <cmath>
#include <limits>
#include <type_traits>

#include "solver/scalar.hpp"

/// \cond INTERNAL
namespace kneedyn {
// Its own namespace, found by argument-dependent lookup: an unqualified sqrt(double) in
// kneedyn must not see these templates (they would hide ::sqrt there).
namespace time_dual {

template <typename S>
struct TimeDual {
  S a = S(0.0);  // value
  S d = S(0.0);  // derivative along the direction ε
  TimeDual() = default;
  TimeDual(double value) : a(value), d(0.0) {}  // NOLINT: implicit, as the physics writes T(2.0), 0.5 * x
  template <typename U = S, typename = std::enable_if_t<!std::is_same<U, double>::value>>
  explicit TimeDual(const S& value) : a(value), d(0.0) {}
  TimeDual(const S& value, const S& derivative) : a(value), d(derivative) {}
  TimeDual& operator+=(const TimeDual& y) { return *this = *this + y; }
  TimeDual& operator-=(const TimeDual& y) { return *this = *this - y; }
  TimeDual& operator*=(const TimeDual& y) { return *this = *this * y; }
  TimeDual& operator/=(const TimeDual& y) { return *this = *this / y; }
};

template <typename S>
TimeDual<S> operator+(const TimeDual<S>& x) { return x; }
template <typename S>
TimeDual<S> operator-(const TimeDual<S>& x) { return {-x.a, -x.d}; }
template <typename S>
TimeDual<S> operator+(const TimeDual<S>& x, const TimeDual<S>& y) { return {x.a + y.a, x.d + y.d}; }
template <typename S>
TimeDual<S> operator-(const TimeDual<S>& x, const TimeDual<S>& y) { return {x.a - y.a, x.d - y.d}; }
template <typename S>
TimeDual<S> operator*(const TimeDual<S>& x, const TimeDual<S>& y) { return {x.a * y.a, x.a * y.d + x.d * y.a}; }
template <typename S>
TimeDual<S> operator/(const TimeDual<S>& x, const TimeDual<S>& y) {
  const S inverse = S(1.0) / y.a;
  const S value = x.a * inverse;
  return {value, (x.d - value * y.d) * inverse};
}
template <typename S>
TimeDual<S> operator+(const TimeDual<S>& x, double s) { return {x.a + s, x.d}; }
template <typename S>
TimeDual<S> operator+(double s, const TimeDual<S>& x) { return {s + x.a, x.d}; }
template <typename S>
TimeDual<S> operator-(const TimeDual<S>& x, double s) { return {x.a - s, x.d}; }
template <typename S>
TimeDual<S> operator-(double s, const TimeDual<S>& x) { return {s - x.a, -x.d}; }
template <typename S>
TimeDual<S> operator*(const TimeDual<S>& x, double s) { return {x.a * s, x.d * s}; }
template <typename S>
TimeDual<S> operator*(double s, const TimeDual<S>& x) { return {s * x.a, s * x.d}; }
template <typename S>
TimeDual<S> operator/(const TimeDual<S>& x, double s) { return {x.a / s, x.d / s}; }
template <typename S>
TimeDual<S> operator/(double s, const TimeDual<S>& x) { return TimeDual<S>(s) / x; }

// Comparisons by value (as ceres::Jet's).
template <typename S>
bool operator<(const TimeDual<S>& x, const TimeDual<S>& y) { return x.a < y.a; }
template <typename S>
bool operator>(const TimeDual<S>& x, const TimeDual<S>& y) { return x.a > y.a; }
template <typename S>
bool operator<=(const TimeDual<S>& x, const TimeDual<S>& y) { return x.a <= y.a; }
template <typename S>
bool operator>=(const TimeDual<S>& x, const TimeDual<S>& y) { return x.a >= y.a; }
template <typename S>
bool operator==(const TimeDual<S>& x, const TimeDual<S>& y) { return x.a == y.a; }
template <typename S>
bool operator!=(const TimeDual<S>& x, const TimeDual<S>& y) { return x.a != y.a; }

template <typename S>
TimeDual<S> sqrt(const TimeDual<S>& x) {
  using std::sqrt;
  const S root = sqrt(x.a);
  return {root, x.d / (2.0 * root)};
}
template <typename S>
TimeDual<S> sin(const TimeDual<S>& x) {
  using std::cos;
  using std::sin;
  return {sin(x.a), cos(x.a) * x.d};
}
template <typename S>
TimeDual<S> cos(const TimeDual<S>& x) {
  using std::cos;
  using std::sin;
  return {cos(x.a), -sin(x.a) * x.d};
}
template <typename S>
TimeDual<S> abs(const TimeDual<S>& x) {
  return x.a < S(0.0) ? -x : x;
}
template <typename S>
bool isfinite(const TimeDual<S>& x) {
  using std::isfinite;
  return isfinite(x.a) && isfinite(x.d);
}

template <typename S>
double ScalarPart(const TimeDual<S>& x) {
  return ::kneedyn::ScalarPart(x.a);
}

// The derivative along ε of a path scalar: TimeDual's d, or the one component of a
// ceres::Jet<T, 1> (ContactRateTerm's path in double).
template <typename S>
S& TimeDerivativeRef(TimeDual<S>& x) {
  return x.d;
}
template <typename S>
const S& TimeDerivativeRef(const TimeDual<S>& x) {
  return x.d;
}
}  // namespace time_dual
using time_dual::TimeDual;

template <typename T>
T& TimeDerivativeRef(ceres::Jet<T, 1>& x) {
  return x.v(0);
}
template <typename T>
const T& TimeDerivativeRef(const ceres::Jet<T, 1>& x) {
  return x.v(0);
}

// TimeDual over double: order 1; over a Jet: 2 (mixed second derivatives). The contact lift
// and the surface charts are exact to this order (contact_kinematics.hpp, height_field.hpp).
template <typename S>
struct DerivativeOrder<TimeDual<S>> : std::integral_constant<int, 1 + DerivativeOrder<S>::value> {};
// A derivative over double is a double-based scalar: the charts and contact points are lifted
// from the double solve, not evaluated in a wide type (height_field.hpp: EvaluateChart).
template <typename S>
struct IsDoubleOrJet<TimeDual<S>> : IsDoubleOrJet<S> {};

}  // namespace kneedyn

namespace Eigen {
template <typename S>
struct NumTraits<kneedyn::time_dual::TimeDual<S>> {
  using Real = kneedyn::time_dual::TimeDual<S>;
  using NonInteger = kneedyn::time_dual::TimeDual<S>;
  using Nested = kneedyn::time_dual::TimeDual<S>;
  using Literal = kneedyn::time_dual::TimeDual<S>;
  static Real dummy_precision() { return Real(1e-12); }
  static Real epsilon() { return Real(std::numeric_limits<double>::epsilon()); }
  static Real highest() { return Real(std::numeric_limits<double>::max()); }
  static Real lowest() { return Real(-std::numeric_limits<double>::max()); }
  static int digits10() { return NumTraits<double>::digits10(); }
  enum {
    IsComplex = 0,
    IsInteger = 0,
    IsSigned = 1,
    RequireInitialization = 1,
    ReadCost = 2 * NumTraits<S>::ReadCost,
    AddCost = 2 * NumTraits<S>::AddCost,
    MulCost = 3 * NumTraits<S>::MulCost,
  };
};
template <typename S, typename BinaryOp>
struct ScalarBinaryOpTraits<kneedyn::time_dual::TimeDual<S>, double, BinaryOp> {
  using ReturnType = kneedyn::time_dual::TimeDual<S>;
};
template <typename S, typename BinaryOp>
struct ScalarBinaryOpTraits<double, kneedyn::time_dual::TimeDual<S>, BinaryOp> {
  using ReturnType = kneedyn::time_dual::TimeDual<S>;
};
}  // namespace Eigen
/// \endcond
