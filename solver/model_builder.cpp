#include "solver/model_builder.hpp"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>

#include "solver/contact_kinematics.hpp"
#include "solver/error.hpp"
#include "solver/ligament.hpp"
#include "solver/units.hpp"

namespace kneedyn {
namespace {

constexpr double kMaxReferenceOffset = 1.0;    // m: |R0| of a usable reference pose
constexpr double kMaxInitialGap = 10.0e-3;     // m: a listed contact further open is an error

ContactPair AsPair(const SurfacePair& s) {
  ContactPair pair;
  pair.femoral_surface = s.femoral;
  pair.tibial_surface = s.tibial;
  return pair;
}

// The initial coordinates and what the consistent initialization holds.
void InitialPose(const Vector6d& reference_q, const InitialStateRequest& request, InitialState* init) {
  using PoseSource = InitialStateRequest::PoseSource;
  init->q = reference_q;
  std::vector<int> given;
  for (int i = 0; i < kNumCoordinates; ++i) {
    if (!request.coordinates[i]) {
      if (request.pose == PoseSource::kExplicit) {
        Throw<InputError>("BuildInitialState", "an explicit pose needs all six coordinates; ", CoordinateName(i),
                          " is missing");
      }
      continue;
    }
    init->q(i) = *request.coordinates[i];
    given.push_back(i);
  }
  if (request.pose == PoseSource::kAssemble && given.empty()) {
    Throw<InputError>("BuildInitialState", "an assembled pose needs at least one coordinate to hold");
  }
  init->qd = request.qd;
  if (IsAtJcsSingularity(std::sin(init->q(kBeta)))) {
    Throw<InputError>("BuildInitialState", "initial pose at the JCS singularity: beta = ", RadToDeg(init->q(kBeta)),
                      " deg (|sin beta| < ", kJcsSingularityTolerance,
                      "); the angular-velocity map E is singular there (docs/model.md §2)");
  }
  if (request.pose == PoseSource::kAssemble) init->held = given;
  if (request.hold) {
    for (int index : request.hold->coordinates) {
      if (std::find(init->held.begin(), init->held.end(), index) == init->held.end()) init->held.push_back(index);
    }
    init->held_velocities = request.hold->velocities;
  } else {
    if (request.pose != PoseSource::kAssemble) init->held = {kAlpha, kBeta, kGamma, kY0};
    init->held_velocities = {0, 1, 2, 3, 4, 5};
  }
}

// Section 1.4: R0 from the medial guesses (Eq. 1.8 with R = I) for the coordinates not
// held; the guesses' coordinates, lateral tibial ones from Eq. 1.8 "one more time".
void ChapterGuesses(const Model& model, const SurfacePair& medial_surfaces, const InitialStateRequest& request,
                    InitialState* init) {
  const auto& medial = request.chapter_guesses[static_cast<int>(Compartment::kMedial)];
  if (!medial || !medial->tibial_xy) {
    Throw<InputError>("BuildInitialState", "chapter guesses need the medial femoral and tibial coordinates");
  }
  HeightSample fs, gs;
  const double xc = medial->femoral_xy[0], yc = medial->femoral_xy[1];
  const double xt = (*medial->tibial_xy)[0], yt = (*medial->tibial_xy)[1];
  if (!medial_surfaces.femoral->Evaluate(xc, yc, &fs) || !medial_surfaces.tibial->Evaluate(xt, yt, &gs)) {
    Throw<InputError>("BuildInitialState", "the chapter guesses (", MToMm(xc), ", ", MToMm(yc), ") mm on the femur and (",
                      MToMm(xt), ", ", MToMm(yt), ") mm on the tibia lie outside the medial surfaces");
  }
  const Matrix3d R = RotationFT(init->q(kAlpha), init->q(kBeta), init->q(kGamma));
  const Vector3d R0 = Vector3d(xc, yc, fs.value) - R * Vector3d(xt, yt, gs.value);
  for (int i = 0; i < 3; ++i) {
    if (std::find(init->held.begin(), init->held.end(), i) == init->held.end()) init->q(i) = R0(i);
  }
  for (size_t k = 0; k < model.contacts.size(); ++k) {
    const auto& g = request.chapter_guesses[static_cast<int>(model.contacts[k].compartment)];
    if (!g) continue;
    ContactGuess& guess = init->contact_guesses[k];
    guess.coordinates[0] = g->femoral_xy[0];
    guess.coordinates[1] = g->femoral_xy[1];
    if (g->tibial_xy) {
      guess.coordinates[2] = (*g->tibial_xy)[0];
      guess.coordinates[3] = (*g->tibial_xy)[1];
    } else {
      const Vector3d p_T = R.transpose() * (Vector3d(guess.coordinates[0], guess.coordinates[1], 0.0) - init->q.head<3>());
      guess.coordinates[2] = p_T.x();
      guess.coordinates[3] = p_T.y();
    }
    guess.normal_force = g->normal_force;
  }
}

// R0 from the medial condition alone (InitialStateRequest::kMedialContact): x0 = xc − (R r′)x
// with the chapter's medial guesses (Eq. 1.8), y0 as given, and z0 from the medial gap
// n · (C − R0) − d − r = 0, which is linear in z0 (docs/model.md §4). R0 is held; unless the
// scene lists its own holds, γ is held and α, β are left to close the lateral contact (the
// gaps' gradients in β and γ are nearly parallel at full extension, in α and β they are not).
void MedialOrigin(const SurfacePair& medial_surfaces, const InitialStateRequest& request, InitialState* init) {
  using PoseSource = InitialStateRequest::PoseSource;
  if (request.guesses != InitialStateRequest::GuessSource::kChapter || request.pose != PoseSource::kReference) {
    Throw<InputError>("BuildInitialState",
                      "an origin from the medial contact needs the reference pose and the chapter's guesses");
  }
  SphereOnPlane medial;
  if (!SphereOnPlaneForm(AsPair(medial_surfaces), &medial)) {
    Throw<InputError>("BuildInitialState", "an origin from the medial contact needs a sphere on a plane medially");
  }
  const auto& guess = *request.chapter_guesses[static_cast<int>(Compartment::kMedial)];
  HeightSample fs, gs;
  const double xt = (*guess.tibial_xy)[0], yt = (*guess.tibial_xy)[1];
  medial_surfaces.femoral->Evaluate(guess.femoral_xy[0], guess.femoral_xy[1], &fs);
  medial_surfaces.tibial->Evaluate(xt, yt, &gs);
  const Matrix3d R = RotationFT(init->q(kAlpha), init->q(kBeta), init->q(kGamma));
  init->q(kX0) = guess.femoral_xy[0] - (R * Vector3d(xt, yt, gs.value)).x();
  const Vector3d n = R * medial.normal_T;
  if (std::abs(n.z()) < 1e-6) {
    Throw<InputError>("BuildInitialState", "the medial plateau is vertical (n_z = ", n.z(),
                      "); the medial gap does not fix z0");
  }
  init->q(kZ0) = (n.dot(medial.centre_F) - medial.offset - medial.radius - n.x() * init->q(kX0) -
                  n.y() * init->q(kY0)) / n.z();
  if (!request.hold) init->held = {kX0, kY0, kZ0, kGamma};
  for (int i : {kX0, kY0, kZ0}) {
    if (std::find(init->held.begin(), init->held.end(), i) == init->held.end()) init->held.push_back(i);
  }
}

}  // namespace

Vector6d SolveReferencePose(const ReferencePoseDescription& d) {
  SphereOnPlane medial, lateral;
  if (!d.medial.femoral || !d.medial.tibial || !d.lateral.femoral || !d.lateral.tibial) {
    Throw<InputError>("SolveReferencePose", "the reference pose needs both the medial and the lateral surfaces");
  }
  if (!SphereOnPlaneForm(AsPair(d.medial), &medial) || !SphereOnPlaneForm(AsPair(d.lateral), &lateral)) {
    Throw<InputError>("SolveReferencePose", "the reference pose is defined for sphere-on-plane compartments only");
  }
  Vector6d q = Vector6d::Zero();
  q(kAlpha) = d.alpha;
  q(kBeta) = d.beta;
  q(kGamma) = d.gamma;
  q(kY0) = d.y0;
  // Each gap n·(C − R0) − d − r = 0 (docs/model.md §4) is linear in (x0, z0).
  const Matrix3d R = RotationFT(q(kAlpha), q(kBeta), q(kGamma));
  Eigen::Matrix2d A;
  Eigen::Vector2d b;
  int row = 0;
  for (const SphereOnPlane* s : {&medial, &lateral}) {
    const Vector3d n = R * s->normal_T;
    A(row, 0) = n.x();
    A(row, 1) = n.z();
    b(row) = n.dot(s->centre_F) - s->offset - s->radius - n.y() * q(kY0);
    ++row;
  }
  const Eigen::Vector2d xz = A.fullPivLu().solve(b);
  q(kX0) = xz(0);
  q(kZ0) = xz(1);
  if (!q.allFinite() || q.head<3>().norm() > kMaxReferenceOffset) {
    Throw<InputError>("SolveReferencePose", "the contact conditions give x0 = ", q(kX0), " m, z0 = ", q(kZ0),
                      " m; no reference pose within 1 m (parallel or degenerate surfaces)");
  }
  return q;
}

void SetLigamentLengths(const Pose& reference, Ligament* lig) {
  lig->reference_length = LigamentSpan_F(*lig, reference).norm();
  lig->slack_length = lig->reference_length / lig->extension_ratio;
}

void SetSlackLength(double slack_length, Ligament* lig) {
  lig->slack_length = slack_length;
  lig->extension_ratio = lig->reference_length / lig->slack_length;
}

void SetLigamentLaw(LigamentLaw law, Ligament* lig) {
  lig->k_parabolic = law == LigamentLaw::kC1Continuous
                         ? lig->k_linear / (4.0 * kLigamentToeStrain * lig->slack_length)
                         : lig->k_parabolic_published;
}

Model BuildModel(const ModelDescription& d, const Vector6d& reference_q) {
  Model model;
  model.mass = d.mass;
  model.inertia_T = d.inertia_T;
  model.gravity_F = d.gravity_F;
  model.ligament_law = d.ligament_law;
  model.angular_velocity_map = d.angular_velocity_map;
  model.contacts = d.contacts;
  model.pulse = d.pulse;
  model.patella = d.patella;
  model.constant_load = d.constant_load;
  const Pose reference = PoseFromCoordinates(reference_q);
  model.ligaments = d.ligaments;
  for (Ligament& lig : model.ligaments) {
    SetLigamentLengths(reference, &lig);
    SetLigamentLaw(d.ligament_law, &lig);
  }
  return model;
}

InitialState BuildInitialState(const Model& model, const Vector6d& reference_q, const SurfacePair& chapter_surfaces,
                               const InitialStateRequest& request) {
  using PoseSource = InitialStateRequest::PoseSource;
  InitialState init;
  InitialPose(reference_q, request, &init);
  init.guesses_source = request.guesses == InitialStateRequest::GuessSource::kChapter ? "chapter" : "pose";
  const Pose pose = PoseFromCoordinates(init.q);
  for (const ContactPair& pair : model.contacts) {
    ContactGuess guess;
    ContactGeometry geo;
    if (ContactKinematics(pair, pose, &geo)) {
      // (Not for an assembled pose: its starting pose is not meant to be in contact.)
      if (request.pose != PoseSource::kAssemble && std::abs(geo.gap) > kMaxInitialGap) {
        Throw<InputError>("BuildInitialState", "the ", CompartmentName(pair.compartment),
                          " compartment is listed among the contacts, but its surfaces are not in contact at the initial pose (gap = ",
                          MToMm(geo.gap), " mm; more than ", MToMm(kMaxInitialGap), " mm)");
      }
      guess.coordinates = {geo.point_F.x(), geo.point_F.y(), geo.point_T.x(), geo.point_T.y()};
    } else if (request.pose != PoseSource::kAssemble) {
      // No contact point at all (the surfaces cannot touch there): before, the scene loaded and
      // the run failed at its first event check with exit 1 and partial files.
      Throw<InputError>("BuildInitialState", "the ", CompartmentName(pair.compartment),
                        " compartment is listed among the contacts, but its surfaces have no contact point at the "
                        "initial pose (rule: a listed contact touches at the start; see its surfaces' coefficients)");
    }
    init.contact_guesses.push_back(guess);
  }
  if (request.guesses == InitialStateRequest::GuessSource::kChapter) {
    ChapterGuesses(model, chapter_surfaces, request, &init);
  }
  if (request.origin == InitialStateRequest::OriginSource::kMedialContact) {
    MedialOrigin(chapter_surfaces, request, &init);
  }
  init.unprojected = request.unprojected_start;
  for (size_t k = 0; k < model.contacts.size(); ++k) {
    const auto& force = request.normal_force_guesses[static_cast<int>(model.contacts[k].compartment)];
    if (force) init.contact_guesses[k].normal_force = *force;
  }
  if (request.contact_guess_offset) {
    // Perturbs every chapter-form coordinate guess (sensitivity studies).
    for (ContactGuess& g : init.contact_guesses) {
      for (double& c : g.coordinates) c += *request.contact_guess_offset;
    }
  }
  return init;
}

Knee BuildKnee(const KneeDescription& d) {
  Knee knee;
  knee.reference_q = SolveReferencePose(d.reference_pose);
  knee.model = BuildModel(d.model, knee.reference_q);
  knee.initial = BuildInitialState(knee.model, knee.reference_q, d.reference_pose.medial, d.initial);
  return knee;
}

}  // namespace kneedyn
