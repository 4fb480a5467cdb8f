// Scene and parameter-set sections: surfaces, compartments and the scene's contacts.
#include <cmath>

#include "scene/internal/scene_keys.hpp"
#include "scene/internal/sections.hpp"
#include "solver/ellipsoid_cap.hpp"
#include "solver/error.hpp"
#include "solver/polynomial_surface.hpp"
#include "solver/units.hpp"

namespace kneedyn::scene_detail {
namespace {

// ellipsoid_cap: centre_mm [3], semi_axes_mm [3] (> 0), orientation_deg [3] (optional:
// rotations about x, then y, then z of the bone's frame; default none).
std::shared_ptr<const HeightField> ParseEllipsoidCap(const Field& f) {
  f.Keys(KeysOf("surface.ellipsoid_cap"));
  const Vector3d centre = f.Required("centre_mm").Vec3() * kMPerMm;
  const Vector3d axes = f.Required("semi_axes_mm").Vec3();
  for (int i = 0; i < 3; ++i) {
    if (!(axes(i) > 0.0 && axes(i) <= kMaxLengthMm)) {
      f.Required("semi_axes_mm").Item(i).Fail(StrCat("must lie in (0, ", kMaxLengthMm, "] mm"));
    }
  }
  Vector3d angles = Vector3d::Zero();
  if (f.Has("orientation_deg")) angles = f.Required("orientation_deg").Vec3() * kRadPerDeg;
  const Matrix3d Q = (Eigen::AngleAxisd(angles.z(), Vector3d::UnitZ()) *
                      Eigen::AngleAxisd(angles.y(), Vector3d::UnitY()) *
                      Eigen::AngleAxisd(angles.x(), Vector3d::UnitX())).toRotationMatrix();
  return std::make_shared<EllipsoidCap>(centre, axes * kMPerMm, Q);
}

// polynomial: origin_mm [3], rotation_z_deg (optional), coefficients_mm {cij: value} with
// i + j <= 4: z_mm = origin_z + sum cij xi_mm^i eta_mm^j.
std::shared_ptr<const HeightField> ParsePolynomial(const Field& f) {
  f.Keys(KeysOf("surface.polynomial"));
  const Vector3d origin = f.Required("origin_mm").Vec3() * kMPerMm;
  const double theta = f.Has("rotation_z_deg") ? DegToRad(f.Required("rotation_z_deg").Double()) : 0.0;
  double c[PolynomialSurface::kMaxDegree + 1][PolynomialSurface::kMaxDegree + 1] = {};
  const Field coeffs = f.Required("coefficients_mm");
  int given = 0;
  for (int i = 0; i <= PolynomialSurface::kMaxDegree; ++i) {
    for (int j = 0; i + j <= PolynomialSurface::kMaxDegree; ++j) {
      const std::string key = StrCat("c", i, j);
      if (!coeffs.Has(key)) continue;
      // z_mm = c ξ_mm^i η_mm^j  →  SI coefficient c · 1000^(i+j−1).
      c[i][j] = coeffs.Required(key).Double() * std::pow(1.0e3, i + j - 1);
      ++given;
    }
  }
  if (given != static_cast<int>(coeffs.Keys().size())) {
    for (const std::string& key : coeffs.Keys()) {
      const bool ok = key.size() == 3 && key[0] == 'c' && key[1] >= '0' && key[2] >= '0' &&
                      (key[1] - '0') + (key[2] - '0') <= PolynomialSurface::kMaxDegree;
      if (!ok) coeffs.Required(key).Fail("unknown coefficient; expected c<i><j> with i + j <= 4 (e.g. c20)");
    }
  }
  if (given == 0) coeffs.Fail("needs at least one coefficient c<i><j> with i + j <= 4 (e.g. c20)");
  return std::make_shared<PolynomialSurface>(origin, theta, c);
}

// Surface factory: a new height field type is one more branch here and one entry in the
// key table (scene_keys.cpp).
std::shared_ptr<const HeightField> ParseSurface(const Field& f) {
  const std::string type = f.Required("type").OneOf(ValuesOf("surface.type"), "surface type");
  if (type == "sphere_cap") {
    f.Keys(KeysOf("surface.sphere_cap"));
    const Vector3d centre = f.Required("centre_mm").Vec3() * kMPerMm;
    return std::make_shared<SphereCap>(centre, MmToM(f.Required("radius_mm").Positive(kMaxLengthMm)));
  }
  if (type == "plane") {
    f.Keys(KeysOf("surface.plane"));
    return std::make_shared<PlaneSurface>(
        f.Required("slope_x").Range(-100.0, 100.0),
        f.Has("slope_y") ? f.Required("slope_y").Range(-100.0, 100.0) : 0.0,
        MmToM(f.Required("offset_mm").Range(-kMaxLengthMm, kMaxLengthMm)));
  }
  if (type == "ellipsoid_cap") return ParseEllipsoidCap(f);
  return ParsePolynomial(f);
}

}  // namespace

SurfacePair ParseCompartment(const Field& f) {
  f.Keys(KeysOf("compartment"));
  SurfacePair c;
  c.femoral = ParseSurface(f.Required("femoral_surface"));
  c.tibial = ParseSurface(f.Required("tibial_surface"));
  return c;
}

// contacts: the compartments in contact at the start; `surfaces` may replace a
// compartment's surfaces.
void ParseContacts(const Field& top, const ParameterSet& ps, ModelDescription* model) {
  const Field f = top.Required("contacts");
  if (top.Has("surfaces")) top.Required("surfaces").Keys(KeysOf("scene.surfaces"));
  for (size_t i = 0; i < f.Size(); ++i) {
    const Field item = f.Item(i);
    const std::string name = item.OneOf(ValuesOf("scene.contacts[]"), "compartment");
    const Compartment c = name == "medial" ? Compartment::kMedial : Compartment::kLateral;
    for (const ContactPair& p : model->contacts) {
      if (p.compartment == c) item.Fail("compartment listed twice");
    }
    SurfacePair data;
    if (top.Has("surfaces") && top.Required("surfaces").Has(name)) {
      data = ParseCompartment(top.Required("surfaces").Required(name));
    } else {
      auto it = ps.compartments.find(name);
      if (it == ps.compartments.end()) item.Fail("the parameter set has no surfaces for this compartment");
      data = it->second;
    }
    ContactPair pair;
    pair.compartment = c;
    pair.femoral_surface = data.femoral;
    pair.tibial_surface = data.tibial;
    model->contacts.push_back(pair);
  }
}

}  // namespace kneedyn::scene_detail
