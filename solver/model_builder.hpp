// Model building: from a plain description of one knee (a parameter set and what a scene
// selects from it, all SI) to the constant Model a run reads and the InitialState it starts
// from. Every derived quantity of the model is computed here and nowhere else:
//   - the reference pose (docs/model.md §6): α, β, γ and y0 given, x0 and z0 from the
//     contact conditions of the medial and lateral sphere-on-plane pairs;
//   - each ligament's L_ref at that pose, L0 = L_ref / e and the law's k_par (Eq. 1.14,
//     docs/model.md §5);
//   - the initial pose, the held coordinates and the chapter-form contact guesses, including
//     the chapter's R0 guess (section 1.4, Eq. 1.8 with the medial guesses).
// The scene loader (scene/), the sweeps (ensembles/) and programs building a knee in code
// call these functions; they need kneedyn_solver alone. Broken rules throw InputError
// naming the value and the rule.
#pragma once

#include <array>
#include <memory>
#include <optional>
#include <vector>

#include "solver/initial_state.hpp"
#include "solver/model.hpp"
#include "solver/pose.hpp"

namespace kneedyn {

// A femoral surface (in F) and a tibial surface (in T) that may touch.
struct SurfacePair {
  std::shared_ptr<const HeightField> femoral;
  std::shared_ptr<const HeightField> tibial;
};

// The pose at full extension that defines L_ref (docs/model.md §6).
struct ReferencePoseDescription {
  double alpha = 0.0, beta = 0.0, gamma = 0.0;  // rad
  double y0 = 0.0;                              // m
  SurfacePair medial, lateral;                  // each a sphere on a plane
};

// The full reference coordinates: x0 and z0 close both gaps at the given angles and y0.
// Throws InputError when a pair is not a sphere on a plane, or when the two contact
// conditions give no pose within 1 m (parallel or degenerate surfaces).
Vector6d SolveReferencePose(const ReferencePoseDescription& description);

// L_ref = |span| at the reference pose and L0 = L_ref / e (Table 1.3).
void SetLigamentLengths(const Pose& reference, Ligament* ligament);
// L0 given instead of e: e = L_ref / L0 (L_ref set before).
void SetSlackLength(double slack_length, Ligament* ligament);
// k_par as the law uses it: the published value, or k_lin / (4 ε1 L0) for the C¹ law.
void SetLigamentLaw(LigamentLaw law, Ligament* ligament);

// The chapter's published guesses for one compartment (section 1.4), SI.
struct ChapterContactGuess {
  std::array<double, 2> femoral_xy{};           // m, on the femoral surface
  std::optional<std::array<double, 2>> tibial_xy;  // m; absent: from the femoral point
  double normal_force = 0.0;                    // N
};

// What the initial state is made of (scene section initial_state).
struct InitialStateRequest {
  enum class PoseSource {
    kReference,  // the reference pose, with any coordinate given replacing its value
    kExplicit,   // all six coordinates given
    kAssemble,   // the given coordinates held, the others solved from the reference pose
  };
  enum class GuessSource { kPose, kChapter };
  PoseSource pose = PoseSource::kReference;
  std::array<std::optional<double>, kNumCoordinates> coordinates;  // SI
  Vector6d qd = Vector6d::Zero();                                   // SI
  // What the consistent initialization holds beyond the defaults: coordinate indices (in
  // order, repeats dropped) and rate indices. Absent: α, β, γ, y0 (or, for kAssemble, the
  // given coordinates) and all six rates.
  struct Hold {
    std::vector<int> coordinates;
    std::vector<int> velocities;
  };
  std::optional<Hold> hold;
  GuessSource guesses = GuessSource::kPose;
  // By compartment (Compartment as index); kChapter needs the medial one with tibial_xy.
  std::array<std::optional<ChapterContactGuess>, kMaxContacts> chapter_guesses;
  std::array<std::optional<double>, kMaxContacts> normal_force_guesses;  // N
  std::optional<double> contact_guess_offset;                           // m, every coordinate
  // Where the initial R0 comes from (docs/model.md §6). kBothContacts: x0 and z0 are solved
  // so that both contacts close at the held angles. kMedialContact, the chapter's words
  // ("thus satisfying the contact condition at the medial side"): x0 from the medial guesses
  // (Eq. 1.8), z0 closing the medial gap; R0 is then held and α, β close the lateral contact.
  // Needs GuessSource::kChapter and PoseSource::kReference.
  enum class OriginSource { kBothContacts, kMedialContact };
  OriginSource origin = OriginSource::kBothContacts;
  // true: InitialState::unprojected (the chapter's DASSL start).
  bool unprojected_start = false;
};

// The constant model but for the quantities derived here.
struct ModelDescription {
  double mass = 0.0;                      // kg
  Vector3d inertia_T = Vector3d::Zero();  // kg m²
  Vector3d gravity_F = Vector3d::Zero();  // m/s²
  LigamentLaw ligament_law = LigamentLaw::kPublished;
  AngularVelocityMapReading angular_velocity_map = AngularVelocityMapReading::kExact;
  // Attachments, k_linear, k_parabolic_published and extension_ratio given; lengths and
  // k_parabolic are set by BuildModel.
  std::vector<Ligament> ligaments;
  std::vector<ContactPair> contacts;
  Pulse pulse;
  ConstantLoad constant_load;
  // Scene section patella (docs/model.md §12); its start guess is set by SolvePatellaStart
  // (solver/patella.hpp) once the initial pose is known.
  std::optional<Patella> patella;
};

// The Model: ligament lengths at `reference_q` and k_par by the law.
Model BuildModel(const ModelDescription& description, const Vector6d& reference_q);

// The initial state of `model` (docs/model.md §6). `chapter_surfaces` are the medial
// surfaces the chapter's guesses lie on (kChapter only). Throws InputError for a pose at
// the JCS singularity, a listed contact more than 10 mm open at a non-assembled pose, and
// chapter guesses that are missing or lie outside the medial surfaces.
InitialState BuildInitialState(const Model& model, const Vector6d& reference_q,
                               const SurfacePair& chapter_surfaces, const InitialStateRequest& request);

// All of it at once, for programs that build a knee in code.
struct KneeDescription {
  ReferencePoseDescription reference_pose;
  ModelDescription model;
  InitialStateRequest initial;
};
struct Knee {
  Model model;
  Vector6d reference_q = Vector6d::Zero();
  InitialState initial;
};
Knee BuildKnee(const KneeDescription& description);

}  // namespace kneedyn
