// Section `patella` (docs/model.md §12; format: reference-data/scenes/README.md): the
// trochlear spheres, the patellar facet planes, the tendon's points and length, the
// quadriceps force. The equilibrium at the start is the builder's (SolvePatellaStart).
#include "scene/internal/scene_keys.hpp"
#include "scene/internal/sections.hpp"
#include "solver/oriented_plane.hpp"
#include "solver/patella.hpp"
#include "solver/units.hpp"

namespace kneedyn::scene_detail {

void ParsePatella(const Field& top, ModelDescription* model) {
  if (!top.Has("patella")) return;
  const Field f = top.Required("patella");
  f.Keys(KeysOf("scene.patella"));
  Patella patella;
  const char* trochlea_keys[2] = {"trochlea_medial", "trochlea_lateral"};
  const char* facet_keys[2] = {"facet_medial", "facet_lateral"};
  for (int i = 0; i < 2; ++i) {
    const Field t = f.Required(trochlea_keys[i]);
    t.Keys(KeysOf("scene.patella.trochlea"));
    const Vector3d centre = t.Required("centre_mm").Vec3() * kMPerMm;
    const double radius = MmToM(t.Required("radius_mm").Positive(kMaxLengthMm));
    const Field p = f.Required(facet_keys[i]);
    p.Keys(KeysOf("scene.patella.facet"));
    const Vector3d normal = p.Required("normal_P").Vec3(1e3);
    if (!(normal.norm() > 0.0)) p.Required("normal_P").Fail("must be a non-zero vector");
    const double offset = MmToM(p.Required("offset_mm").Range(-kMaxLengthMm, kMaxLengthMm));
    patella.facet[i].compartment = static_cast<Compartment>(i);
    patella.facet[i].femoral_surface = std::make_shared<SphereCap>(centre, radius);
    patella.facet[i].tibial_surface = std::make_shared<OrientedPlane>(normal, offset);
  }
  patella.apex_P = f.Required("apex_P_mm").Vec3() * kMPerMm;
  patella.base_P = f.Required("base_P_mm").Vec3() * kMPerMm;
  // The patella's extent is along P's z, from the apex to the base (the off-patella check of
  // its facet contacts, docs/model.md §12): a patella without one (apex = base) is no patella.
  if (!(std::abs(MToMm(patella.base_P.z() - patella.apex_P.z())) >= 1.0)) {
    f.Required("base_P_mm").Fail(StrCat("z = ", MToMm(patella.base_P.z()), " mm lies within 1 mm of apex_P_mm's z = ",
                                        MToMm(patella.apex_P.z()), " mm: the patella's extent runs along P's z from "
                                        "its apex to its base, at least 1 mm long"));
  }
  patella.tuberosity_T = f.Required("tuberosity_T_mm").Vec3() * kMPerMm;
  patella.tendon_length = MmToM(f.Required("tendon_length_mm").Positive(kMaxLengthMm));
  if (f.Has("facet_liftoff")) patella.facet_liftoff = f.Required("facet_liftoff").Bool();
  const Field q = f.Required("quadriceps");
  q.Keys(KeysOf("scene.patella.quadriceps"));
  QuadricepsForce& quadriceps = patella.quadriceps;
  quadriceps.shape =
      ParseQuadricepsShape(q.Required("shape").OneOf(ValuesOf("scene.patella.quadriceps.shape"), "quadriceps shape"));
  // A key the shape does not use would be ignored: refused, naming the shape and its rule.
  if (quadriceps.shape == QuadricepsShape::kConstant) {
    for (const char* key : {"baseline_N", "duration_s"}) {
      if (q.Has(key)) {
        q.Required(key).Fail("not used by quadriceps shape constant (F = magnitude_N at every t); baseline_N "
                             "and duration_s belong to the shapes ramp and half_sine");
      }
    }
  }
  quadriceps.magnitude = q.Required("magnitude_N").Range(-kMaxForceN, kMaxForceN);
  if (q.Has("baseline_N")) quadriceps.baseline = q.Required("baseline_N").Range(-kMaxForceN, kMaxForceN);
  if (q.Has("duration_s")) quadriceps.duration = q.Required("duration_s").Range(kMinDurationS, kMaxDurationS);
  if (q.Has("direction_F")) {
    const Vector3d d = q.Required("direction_F").Vec3(1e3);
    if (!(d.norm() > 0.0)) q.Required("direction_F").Fail("must be a non-zero vector");
    quadriceps.direction_F = d.normalized();
  }
  // A massless patella has no equilibrium without a pulling quadriceps.
  std::string why;
  if (!QuadricepsPositive(quadriceps, &why)) {
    const char* key = why.find("baseline_N") != std::string::npos ? "baseline_N" : "magnitude_N";
    if (q.Has(key)) q.Required(key).Fail(why);
    q.Fail(why);
  }
  model->patella = patella;
}

}  // namespace kneedyn::scene_detail
