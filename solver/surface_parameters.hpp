// What a surface type reads from a scene file, declared by the type itself: its `type:` name
// (kSceneType) and its parameters (kSceneParameters), a tuple of the descriptors below in the
// order its constructor takes them. The scene loader (scene/surfaces.cpp) reads, checks and
// converts each descriptor the same way for every type, so a surface type carries no file
// code and the solver stays free of YAML. Keys are in the file's units (mm, degrees); the
// constructor receives SI (m, rad).
//
//   static constexpr const char* kSceneType = "sphere_cap";
//   static constexpr auto kSceneParameters =
//       std::make_tuple(surface_parameter::PointMm{"centre_mm"}, surface_parameter::PositiveLengthMm{"radius_mm"});
#pragma once

namespace kneedyn {

// Highest degree i + j of a polynomial height field's terms c_ij ξ^i η^j (PolynomialSurface).
constexpr int kMaxPolynomialDegree = 4;

// Coefficients c_ij in SI (m^(1−i−j)); zero for i + j > kMaxPolynomialDegree.
struct PolynomialCoefficients {
  double c[kMaxPolynomialDegree + 1][kMaxPolynomialDegree + 1] = {};
};

namespace surface_parameter {

// A point [x, y, z] in mm, each |value| within the loader's length limit → Vector3d, m.
struct PointMm {
  const char* key;
};
// Three semi-axes [a, b, c] in mm, each in (0, length limit] → Vector3d, m.
struct SemiAxesMm {
  const char* key;
};
// A length in (0, length limit] mm → double, m.
struct PositiveLengthMm {
  const char* key;
};
// A signed length within ± the length limit, mm → double, m.
struct LengthMm {
  const char* key;
};
// A slope (dimensionless) in [−100, 100]; an optional one defaults to 0.
struct Slope {
  const char* key;
  bool optional;
};
// An optional angle in degrees → double, rad (default 0).
struct AngleDeg {
  const char* key;
};
// Optional rotations [x, y, z] in degrees about the bone's x, then y, then z axis →
// Matrix3d Rz Ry Rx (default the identity).
struct RotationXyzDeg {
  const char* key;
};
// A mapping {c<i><j>: value} with i + j ≤ kMaxPolynomialDegree, at least one term, in mm:
// z_mm = Σ c_ij ξ_mm^i η_mm^j → PolynomialCoefficients in SI.
struct PolynomialCoefficientsMm {
  const char* key;
};

}  // namespace surface_parameter
}  // namespace kneedyn
