// Scene sections: body, gravity, pulse, constant_load.
#include "scene/internal/scene_keys.hpp"
#include "scene/internal/sections.hpp"
#include "solver/error.hpp"
#include "solver/loads.hpp"

namespace kneedyn::scene_detail {

// body: overrides of the parameter set's mass and inertia.
void ParseBody(const Field& top, const ParameterSet& ps, ModelDescription* model) {
  model->mass = ps.mass;
  model->inertia_T = ps.inertia_T;
  if (top.Has("angular_velocity_map")) {
    // The body's kinematics: the exact map or the printed Eq. 1.20b (docs/model.md §2).
    const std::string map =
        top.Required("angular_velocity_map").OneOf(ValuesOf("scene.angular_velocity_map"), "angular velocity map");
    model->angular_velocity_map =
        map == "printed_eq_1_20b" ? AngularVelocityMapReading::kPrintedEq1_20b : AngularVelocityMapReading::kExact;
  }
  if (!top.Has("body")) return;
  const Field body = top.Required("body");
  body.Keys(KeysOf("scene.body"));
  if (body.Has("mass_kg")) model->mass = body.Required("mass_kg").Range(kMinMassKg, kMaxMassKg);
  if (body.Has("principal_inertia_kg_m2")) {
    const Field f = body.Required("principal_inertia_kg_m2");
    model->inertia_T = f.Vec3(1e3);
    for (int i = 0; i < 3; ++i) {
      if (!(model->inertia_T(i) > 0.0)) f.Item(i).Fail("must be > 0");
    }
  }
}

// gravity: on or off; direction and magnitude default to the parameter set's.
void ParseGravity(const Field& top, const ParameterSet& ps, ModelDescription* model) {
  const Field f = top.Required("gravity");
  f.Keys(KeysOf("scene.gravity"));
  const bool enabled = f.Required("enabled").Bool();
  // A key gravity does not use would be ignored: refused, as the pulse's (below).
  if (!enabled) {
    for (const char* unused : {"magnitude_m_s2", "direction_F"}) {
      if (f.Has(unused)) f.Required(unused).Fail("is not used: gravity.enabled is false (rule: give it only with gravity on)");
    }
  }
  Vector3d dir = ps.gravity_direction_F;
  double g = ps.g;
  if (f.Has("direction_F")) {
    dir = f.Required("direction_F").Vec3(1e3);
    // A direction is a direction whether gravity is on or not (the parameter set's is checked where it is read).
    if (!(dir.norm() > 0.0)) f.Required("direction_F").Fail("must be a non-zero vector");
  }
  if (f.Has("magnitude_m_s2")) g = f.Required("magnitude_m_s2").NonNegative(100.0);
  if (enabled) model->gravity_F = g * dir.normalized();
}

// pulse: shape (solver/loads.hpp), amplitude and duration unless none, direction.
void ParsePulse(const Field& top, ModelDescription* model) {
  const Field f = top.Required("pulse");
  f.Keys(KeysOf("scene.pulse"));
  model->pulse.shape = ParsePulseShape(f.Required("shape").OneOf(ValuesOf("scene.pulse.shape"), "pulse shape"));
  // A key the shape does not use would be ignored: refused, naming the shape and its rule.
  if (model->pulse.shape == PulseShape::kNone) {
    for (const char* key : {"amplitude_N", "duration_s", "direction_T"}) {
      if (f.Has(key)) {
        f.Required(key).Fail("not used by pulse shape none (no pulse); amplitude_N, duration_s and direction_T "
                             "belong to the other shapes");
      }
    }
  } else {
    model->pulse.amplitude = f.Required("amplitude_N").NonNegative(kMaxForceN);
    model->pulse.duration = f.Required("duration_s").Range(kMinDurationS, kMaxDurationS);
  }
  if (f.Has("direction_T")) {
    const Vector3d d = f.Required("direction_T").Vec3(1e3);
    if (!(d.norm() > 0.0)) f.Required("direction_T").Fail("must be a non-zero vector");
    model->pulse.direction_T = d.normalized();
  }
}

void ParseConstantLoad(const Field& top, ModelDescription* model) {
  if (!top.Has("constant_load")) return;
  const Field f = top.Required("constant_load");
  f.Keys(KeysOf("scene.constant_load"));
  if (f.Has("force_F_N")) model->constant_load.force_F = f.Required("force_F_N").Vec3(kMaxForceN);
  if (f.Has("torque_T_N_m")) model->constant_load.torque_T = f.Required("torque_T_N_m").Vec3(1e4);
}

}  // namespace kneedyn::scene_detail
