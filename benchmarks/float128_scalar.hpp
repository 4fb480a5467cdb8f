// IEEE quadruple precision (113-bit mantissa, ε = 1.9e-34; GCC's __float128 through
// libquadmath) as a scalar of the templated physics, for the extended-precision references
// (extended_reference.hpp): Boost.Multiprecision's float128 with its Eigen traits, and the
// ScalarPart the physics templates call for their branch decisions (found by
// argument-dependent lookup: the physics headers need not know the type).
#pragma once

#include <boost/multiprecision/eigen.hpp>
#include <boost/multiprecision/float128.hpp>

namespace boost {
namespace multiprecision {
inline double ScalarPart(const float128& x) { return x.convert_to<double>(); }
}  // namespace multiprecision
}  // namespace boost

namespace kneedyn {
namespace bench {
using Float128 = boost::multiprecision::float128;
}  // namespace bench
}  // namespace kneedyn
