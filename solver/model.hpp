// The constant model of one scene (kept apart from the mutable workspaces).
// Built once by the model builder (model_builder.hpp), from a scene file (the loader,
// scene/scene.hpp) or from code; never modified by a run.
// All quantities SI. Only what the scene names is present.
#pragma once

#include <array>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "solver/height_field.hpp"
#include "solver/rotation.hpp"
#include "solver/scalar.hpp"

namespace kneedyn {

// Ligament force law variant (docs/model.md §5).
enum class LigamentLaw {
  kPublished,     // Table 1.2 values as printed: small jump at ε = 2ε1
  kC1Continuous,  // k_par recomputed as k_lin / (4 ε1 L0): C¹ at ε = 2ε1
};
inline constexpr LigamentLaw kLigamentLaws[] = {LigamentLaw::kPublished, LigamentLaw::kC1Continuous};
// The scene's and summary.json's name of a law (scene key ligament_law). A switch without a
// default, so that a new law that is not named here is a compiler warning.
inline const char* LigamentLawName(LigamentLaw law) {
  switch (law) {
    case LigamentLaw::kPublished: return "published";
    case LigamentLaw::kC1Continuous: return "c1_continuous";
  }
  return "?";
}

// Strain where the parabolic toe region ends is 2 ε1 (chapter Eq. 1.14).
constexpr double kLigamentToeStrain = 0.03;  // ε1

// One straight, tension-only spring element (chapter Eqs. 1.14–1.16, Tables 1.1–1.3).
struct Ligament {
  std::string name;                // e.g. "ACL anterior"
  Vector3d p_FoA_F;                // femoral attachment in F, m
  Vector3d p_ToB_T;                // tibial attachment in T (origin at centre of mass), m
  double k_linear = 0.0;           // N/m, linear region
  double k_parabolic = 0.0;        // N/m², toe region (as used; see LigamentLaw)
  double k_parabolic_published = 0.0;  // N/m², Table 1.2 value
  double extension_ratio = 1.0;    // e = L_ref / L0 (Table 1.3)
  double reference_length = 0.0;   // L_ref at the reference pose, m
  double slack_length = 0.0;       // L0 = L_ref / e, m
};

enum class Compartment { kMedial = 0, kLateral = 1 };
constexpr int kMaxContacts = 2;
const char* CompartmentName(Compartment c);  // "medial" / "lateral"
// An element's name as output columns and event names spell it (spaces, '-', '/' as '_'):
// "ACL anterior" -> "ACL_anterior" (strain_ACL_anterior, kink_ACL_anterior).
std::string ColumnSafeName(const std::string& name);

struct ContactPair {
  Compartment compartment = Compartment::kMedial;
  std::shared_ptr<const HeightField> femoral_surface;  // in F
  std::shared_ptr<const HeightField> tibial_surface;   // in T
  // Contact kinematics of the pair: solver/contact_kinematics.hpp (closed form for a
  // sphere on a plane, a local solve otherwise).
};

// External pulse at the centre of mass, along a tibial direction (docs/model.md §7).
enum class PulseShape {
  kNone,
  kReconstructed,  // A (t/t0) sin(2π t/t0) exp(−4.73 t/t0), Eq. 1.62 as reconstructed
  kHalfSine,       // A sin(π t/t0) on [0, t0], zero after
  kReconstructedPeak,  // kReconstructed scaled so that its peak is A (reconstruction study)
  kDampedSine,         // A sin(2π t/t0) exp(−4.73 t/t0), another reading of Eq. 1.62
};

struct Pulse {
  PulseShape shape = PulseShape::kNone;
  double amplitude = 0.0;  // A, N
  double duration = 0.1;   // t0, s
  Vector3d direction_T = Vector3d(0.0, -1.0, 0.0);  // unit, turns with the tibia
};

// Extra constant force and torque on the tibia, for verification scenes
// (reference-data/hanging_element_knee.md, tests/exact_solution_test.cpp).
struct ConstantLoad {
  Vector3d force_F = Vector3d::Zero();   // N, at the centre of mass
  Vector3d torque_T = Vector3d::Zero();  // N m
};

// Magnitude of the quadriceps force against time (docs/model.md §12):
//   constant   F_Q = magnitude
//   ramp       F_Q = baseline + (magnitude − baseline) min(t / duration, 1)
//   half_sine  F_Q = baseline + magnitude sin(π t / duration) on [0, duration], baseline after
enum class QuadricepsShape { kConstant, kRamp, kHalfSine };

struct QuadricepsForce {
  QuadricepsShape shape = QuadricepsShape::kConstant;
  double magnitude = 0.0;  // N
  double baseline = 0.0;   // N (ramp start, half-sine base)
  double duration = 0.1;   // s
  Vector3d direction_F = Vector3d::UnitZ();  // unit line of action on the patella, fixed in F
};

// The patella (docs/model.md §12): a massless third body whose pose relative to the femur
// is the solution of its equilibrium (solver/patella.hpp). Frame P: origin on the
// patellar ridge, axes parallel to F in the reference patellar pose.
struct Patella {
  // Trochlear facet of the femur (in F) against the patellar facet (in P, normal towards
  // the femur): medial = facet[0], lateral = facet[1]. ContactPair's "tibial" surface is
  // the patellar one here; the contact kinematics are those of the tibia (contact.hpp).
  std::array<ContactPair, 2> facet;
  Vector3d apex_P = Vector3d::Zero();        // patellar apex (tendon origin), m
  Vector3d base_P = Vector3d::Zero();        // patellar base (quadriceps insertion), m
  Vector3d tuberosity_T = Vector3d::Zero();  // tibial tuberosity (tendon insertion), m
  double tendon_length = 0.0;                // rigid patellar tendon, apex to tuberosity, m
  QuadricepsForce quadriceps;
  // A facet may lift off and re-contact (docs/model.md §12, scene key facet_liftoff); false:
  // both facets always press (λ_i of either sign), the chapter's two-contact model.
  bool facet_liftoff = false;
  // Starting guess of the equilibrium solve (PatellaUnknowns, patella.hpp) and the tibial
  // coordinates q it solves at: the model builder's solution at the initial pose.
  std::array<double, 17> start_unknowns{};
  Vector6d start_q = Vector6d::Zero();
};

struct Model {
  double mass = 0.0;                               // kg
  Vector3d inertia_T = Vector3d::Zero();           // principal moments about the COM, kg m²
  Vector3d gravity_F = Vector3d::Zero();           // m/s² (zero when gravity is off)
  std::vector<Ligament> ligaments;                 // only those the scene names
  std::vector<ContactPair> contacts;               // only those the scene names
  Pulse pulse;
  ConstantLoad constant_load;
  // Verification only (manufactured solutions, tests/exact_solution_test.cpp): an extra
  // time-dependent force at the COM (N, F components) and torque (N m, T components), added
  // to the constant load. Never set by a scene; empty = none.
  std::function<void(double t, Vector3d* force_F, Vector3d* torque_T)> manufactured_load;
  LigamentLaw ligament_law = LigamentLaw::kPublished;
  // The exact angular velocity, or the chapter's printed Eq. 1.20b (docs/model.md §2).
  AngularVelocityMapReading angular_velocity_map = AngularVelocityMapReading::kExact;
  // Present only when the scene has a patella: section; then the patellar tendon force
  // acts on the tibia at the tuberosity (dynamics.hpp).
  std::optional<Patella> patella;

  // Index of the contact pair for a compartment, or -1 when the scene has none there.
  int ContactIndex(Compartment c) const;
};

}  // namespace kneedyn
