// Scene and parameter-set sections: surfaces, compartments and the scene's contacts.
#include <algorithm>
#include <cmath>
#include <tuple>

#include "scene/internal/scene_keys.hpp"
#include "scene/internal/sections.hpp"
#include "solver/error.hpp"
#include "solver/surface_types.hpp"
#include "solver/units.hpp"

namespace kneedyn::scene_detail {
namespace {

namespace sp = surface_parameter;

// One reader per parameter descriptor (solver/surface_parameters.hpp): the file's value,
// checked, in SI.
Vector3d Read(const Field& f, const sp::PointMm& p) { return f.Required(p.key).Vec3() * kMPerMm; }

Vector3d Read(const Field& f, const sp::SemiAxesMm& p) {
  const Field field = f.Required(p.key);
  const Vector3d axes = field.Vec3();
  for (int i = 0; i < 3; ++i) {
    if (!(axes(i) > 0.0 && axes(i) <= kMaxLengthMm)) {
      field.Item(i).Fail(StrCat("must lie in (0, ", kMaxLengthMm, "] mm"));
    }
  }
  return axes * kMPerMm;
}

double Read(const Field& f, const sp::PositiveLengthMm& p) { return MmToM(f.Required(p.key).Positive(kMaxLengthMm)); }

double Read(const Field& f, const sp::LengthMm& p) {
  return MmToM(f.Required(p.key).Range(-kMaxLengthMm, kMaxLengthMm));
}

double Read(const Field& f, const sp::Slope& p) {
  if (p.optional && !f.Has(p.key)) return 0.0;
  return f.Required(p.key).Range(-100.0, 100.0);
}

double Read(const Field& f, const sp::AngleDeg& p) { return f.Has(p.key) ? DegToRad(f.Required(p.key).Double()) : 0.0; }

Matrix3d Read(const Field& f, const sp::RotationXyzDeg& p) {
  Vector3d angles = Vector3d::Zero();
  if (f.Has(p.key)) angles = f.Required(p.key).Vec3() * kRadPerDeg;
  return (Eigen::AngleAxisd(angles.z(), Vector3d::UnitZ()) * Eigen::AngleAxisd(angles.y(), Vector3d::UnitY()) *
          Eigen::AngleAxisd(angles.x(), Vector3d::UnitX()))
      .toRotationMatrix();
}

// z_mm = c ξ_mm^i η_mm^j  →  SI coefficient c · 1000^(i+j−1).
PolynomialCoefficients Read(const Field& f, const sp::PolynomialCoefficientsMm& p) {
  PolynomialCoefficients out;
  const Field coeffs = f.Required(p.key);
  int given = 0;
  for (int i = 0; i <= kMaxPolynomialDegree; ++i) {
    for (int j = 0; i + j <= kMaxPolynomialDegree; ++j) {
      const std::string key = StrCat("c", i, j);
      if (!coeffs.Has(key)) continue;
      out.c[i][j] = coeffs.Required(key).Double() * std::pow(1.0e3, i + j - 1);
      if (!std::isfinite(out.c[i][j])) {  // 1e300 mm^-3 overflows in SI: named here, in the file's units
        coeffs.Required(key).Fail(StrCat("is past double's range in SI units (x 1000^", i + j - 1, ")"));
      }
      ++given;
    }
  }
  if (given != static_cast<int>(coeffs.Keys().size())) {
    for (const std::string& key : coeffs.Keys()) {
      const bool ok = key.size() == 3 && key[0] == 'c' && key[1] >= '0' && key[2] >= '0' &&
                      (key[1] - '0') + (key[2] - '0') <= kMaxPolynomialDegree;
      if (!ok) {
        coeffs.Required(key).Fail(
            StrCat("unknown coefficient; expected c<i><j> with i + j <= ", kMaxPolynomialDegree, " (e.g. c20)"));
      }
    }
  }
  if (given == 0) {
    coeffs.Fail(StrCat("needs at least one coefficient c<i><j> with i + j <= ", kMaxPolynomialDegree, " (e.g. c20)"));
  }
  return out;
}

// A surface of type Surface from its mapping: its keys checked, its parameters read in the
// order they are declared (a braced list evaluates left to right, so the first bad value in
// that order is the one reported), then its constructor.
template <typename Surface>
std::shared_ptr<const HeightField> ReadSurface(const Field& f) {
  // Looked up once per type.
  static const std::vector<const char*>& keys = KeysOf(StrCat("surface.", Surface::kSceneType));
  f.Keys(keys);
  const auto values = std::apply([&f](const auto&... p) { return std::tuple{Read(f, p)...}; }, Surface::kSceneParameters);
  return std::apply([](const auto&... v) { return std::make_shared<Surface>(v...); }, values);
}

// The surface factory: the type named by `type:` among solver/surface_types.hpp's scene types.
std::shared_ptr<const HeightField> ParseSurface(const Field& f) {
  const std::string type = f.Required("type").OneOf(ValuesOf("surface.type"), "surface type");
  std::shared_ptr<const HeightField> surface;
  ForEachSurfaceType(SceneSurfaceTypes{}, [&](auto tag) {
    using Surface = typename decltype(tag)::type;
    if (surface == nullptr && type == Surface::kSceneType) surface = ReadSurface<Surface>(f);
  });
  return surface;
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
  // Surfaces for a compartment the model leaves out would be read by nothing (and went
  // unchecked): refused, as ligament_parameters of an element not selected.
  if (top.Has("surfaces")) RefuseCompartmentsNotInContacts(top.Required("surfaces"), *model);
}

void RefuseCompartmentsNotInContacts(const Field& section, const ModelDescription& model) {
  for (const std::string& name : section.Keys()) {
    if (std::none_of(model.contacts.begin(), model.contacts.end(),
                     [&](const ContactPair& p) { return name == CompartmentName(p.compartment); })) {
      section.Required(name).Fail("not a compartment of this scene's contacts (field 'contacts'): it would not be used");
    }
  }
}

}  // namespace kneedyn::scene_detail
