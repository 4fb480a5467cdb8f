#include "crosscheck/simbody/simbody_knee.hpp"

#include <Simbody.h>

#include <Eigen/Dense>
#include <ceres/version.h>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>

#include "solver/contact_kinematics.hpp"  // SphereOnPlaneForm: the scene's surfaces as sphere + plane data
#include "solver/error.hpp"
#include "solver/loads.hpp"  // PulseShapeName, PulsePeakFactor: the pulse as summary.json names it
#include "solver/pose.hpp"  // JCS output conversion only (CoordinateVelocity/Acceleration)
#include "solver/units.hpp"

namespace kneedyn {
namespace simbody {

using SimTK::Real;
using SimTK::Stage;
using SimTK::State;
using SimTK::Vec3;

namespace {

const double kNaN = std::numeric_limits<double>::quiet_NaN();

// ---------------------------------------------------------------------------------------
// The chapter's laws, written again here (not kneedyn's solver/ligament.* or loads.*).

// ε1 of Eq. 1.14: the toe region ends at ε = 2 ε1.
constexpr double kToeStrain = 0.03;

enum Branch : int { kToe = 0, kLinear = 1 };

// Eq. 1.14 on a given branch (the published law's branches continued past the kink).
double Tension(const Ligament& lig, double length, int branch) {
  const double L0 = lig.slack_length;
  if (branch == kToe) {
    const double x = length - L0;
    return x > 0.0 ? lig.k_parabolic * x * x : 0.0;
  }
  return lig.k_linear * (length - (1.0 + kToeStrain) * L0);
}

double KinkLength(const Ligament& lig) { return (1.0 + 2.0 * kToeStrain) * lig.slack_length; }

int BranchByLength(const Ligament& lig, double length) {
  return length <= KinkLength(lig) ? kToe : kLinear;
}

// Strain energy: ∫ F dL of Eq. 1.14 by length (continuous; dV/dL = F on each side).
double StrainEnergy(const Ligament& lig, double length) {
  const double L0 = lig.slack_length;
  const double x = length - L0;
  if (x <= 0.0) return 0.0;
  const double xk = 2.0 * kToeStrain * L0;
  const double toe = lig.k_parabolic * std::pow(std::min(x, xk), 3) / 3.0;
  if (x <= xk) return toe;
  // ∫_{xk}^{x} k_lin (s − ε1 L0) ds
  const double a = x - kToeStrain * L0, b = xk - kToeStrain * L0;
  return toe + 0.5 * lig.k_linear * (a * a - b * b);
}

// The reconstructed shape s sin(2πs) e^{−4.73 s} of Eq. 1.62 (s = t/t0).
double ReconstructedShape(double s) { return s * std::sin(2.0 * SimTK::Pi * s) * std::exp(-4.73 * s); }

// Its maximum over s >= 0, found here (not taken from kneedyn): the largest of a 1e-3 grid
// on [0, 1] (the envelope s e^{−4.73 s} makes later lobes smaller), refined by golden
// section to round-off.
double ReconstructedShapePeak() {
  double best_s = 0.0;
  for (int i = 1; i <= 1000; ++i) {
    if (ReconstructedShape(i * 1e-3) > ReconstructedShape(best_s)) best_s = i * 1e-3;
  }
  double a = best_s - 1e-3, b = best_s + 1e-3;
  const double g = 0.5 * (std::sqrt(5.0) - 1.0);
  for (int it = 0; it < 100; ++it) {
    const double c = b - g * (b - a), d = a + g * (b - a);
    if (ReconstructedShape(c) > ReconstructedShape(d)) b = d; else a = c;
  }
  return ReconstructedShape(0.5 * (a + b));
}

// Eq. 1.62 as reconstructed (also scaled to peak A), the damped-sine reading, and the
// half-sine pulse (docs/model.md §7; the reconstruction study's readings).
double PulseValue(const Pulse& p, double t) {
  if (t < 0.0) return 0.0;
  const double s = t / p.duration;
  switch (p.shape) {
    case PulseShape::kNone: return 0.0;
    case PulseShape::kReconstructed: return p.amplitude * ReconstructedShape(s);
    case PulseShape::kReconstructedPeak: {
      static const double peak = ReconstructedShapePeak();
      return p.amplitude * ReconstructedShape(s) / peak;
    }
    case PulseShape::kDampedSine: return p.amplitude * std::sin(2.0 * SimTK::Pi * s) * std::exp(-4.73 * s);
    case PulseShape::kHalfSine: return s <= 1.0 ? p.amplitude * std::sin(SimTK::Pi * s) : 0.0;
  }
  return 0.0;
}

Vec3 ToVec3(const Vector3d& v) { return Vec3(v.x(), v.y(), v.z()); }
Vector3d ToEigen(const Vec3& v) { return Vector3d(v[0], v[1], v[2]); }

// ---------------------------------------------------------------------------------------
// Forces.

class LigamentForces : public SimTK::Force::Custom::Implementation {
 public:
  LigamentForces(const SimTK::GeneralForceSubsystem& forces, const SimTK::MobilizedBody& tibia,
                 const Model& model)
      : forces_(forces), tibia_(tibia), model_(model) {}

  bool locks_branches() const { return model_.ligament_law == LigamentLaw::kPublished; }

  void realizeTopology(State& state) const override {
    branch_index_ = forces_.allocateDiscreteVariable(
        state, Stage::Dynamics,
        new SimTK::Value<std::vector<int>>(std::vector<int>(model_.ligaments.size(), -1)));
  }
  const std::vector<int>& Branches(const State& s) const {
    return SimTK::Value<std::vector<int>>::downcast(forces_.getDiscreteVariable(s, branch_index_)).get();
  }
  std::vector<int>& UpdBranches(State& s) const {
    return SimTK::Value<std::vector<int>>::updDowncast(forces_.updDiscreteVariable(s, branch_index_)).upd();
  }
  double Length(const State& s, size_t j) const {
    const Ligament& lig = model_.ligaments[j];
    return (ToVec3(lig.p_FoA_F) - tibia_.findStationLocationInGround(s, ToVec3(lig.p_ToB_T))).norm();
  }
  // The branch in force: locked (published law) or by length.
  double TensionAt(const State& s, size_t j, double length) const {
    const Ligament& lig = model_.ligaments[j];
    const int locked = locks_branches() ? Branches(s)[j] : -1;
    return Tension(lig, length, locked >= 0 ? locked : BranchByLength(lig, length));
  }

  void calcForce(const State& s, SimTK::Vector_<SimTK::SpatialVec>& body_forces,
                 SimTK::Vector_<Vec3>&, SimTK::Vector&) const override {
    for (size_t j = 0; j < model_.ligaments.size(); ++j) {
      const Ligament& lig = model_.ligaments[j];
      const Vec3 station_B = ToVec3(lig.p_ToB_T);
      const Vec3 span_G = ToVec3(lig.p_FoA_F) - tibia_.findStationLocationInGround(s, station_B);
      const double length = span_G.norm();
      const double tension = TensionAt(s, j, length);
      if (tension == 0.0) continue;
      // On the tibia at its attachment, towards the femoral attachment (docs/model.md §5).
      tibia_.applyForceToBodyPoint(s, station_B, tension * span_G / length, body_forces);
    }
  }
  Real calcPotentialEnergy(const State& s) const override {
    double v = 0.0;
    for (size_t j = 0; j < model_.ligaments.size(); ++j) v += StrainEnergy(model_.ligaments[j], Length(s, j));
    return v;
  }

 private:
  const SimTK::GeneralForceSubsystem& forces_;
  const SimTK::MobilizedBody& tibia_;
  const Model& model_;
  mutable SimTK::DiscreteVariableIndex branch_index_;
};

// The pulse at the centre of mass along R d_T (it turns with the tibia), and the scene's
// constant load (verification scenes).
class PulseForce : public SimTK::Force::Custom::Implementation {
 public:
  PulseForce(const SimTK::MobilizedBody& tibia, const Model& model) : tibia_(tibia), model_(model) {}
  void calcForce(const State& s, SimTK::Vector_<SimTK::SpatialVec>& body_forces,
                 SimTK::Vector_<Vec3>&, SimTK::Vector&) const override {
    const SimTK::Rotation& R_GB = tibia_.getBodyRotation(s);
    const Vec3 f_G = PulseValue(model_.pulse, s.getTime()) * (R_GB * ToVec3(model_.pulse.direction_T)) +
                     ToVec3(model_.constant_load.force_F);
    tibia_.applyForceToBodyPoint(s, Vec3(0), f_G, body_forces);
    tibia_.applyBodyTorque(s, R_GB * ToVec3(model_.constant_load.torque_T), body_forces);
  }
  Real calcPotentialEnergy(const State& s) const override {
    return -~ToVec3(model_.constant_load.force_F) * tibia_.getBodyOriginLocation(s);
  }

 private:
  const SimTK::MobilizedBody& tibia_;
  const Model& model_;
};

// ---------------------------------------------------------------------------------------
// The assembled system.

class Knee;

// Triggered handlers call back into the Knee.
class KneeHandler : public SimTK::TriggeredEventHandler {
 public:
  enum Kind { kLiftoff, kRecontact, kKink, kEnd };
  KneeHandler(Knee* knee, Kind kind, int index, Stage stage)
      : SimTK::TriggeredEventHandler(stage), knee_(knee), kind_(kind), index_(index) {}
  Real getValue(const State& s) const override;
  void handleEvent(State& s, Real accuracy, bool& terminate) const override;

 private:
  Knee* knee_;
  Kind kind_;
  int index_;
};

constexpr double kRecontactHysteresis = 1.0e-9;  // m, as kneedyn's floor (README)

class Knee {
 public:
  Knee(const Scene& scene, const Options& options)
      : scene_(scene), model_(scene.model), options_(options), matter_(system_), forces_(system_) {
    const Model& m = model_;
    SimTK::Body::Rigid body(SimTK::MassProperties(
        m.mass, Vec3(0), SimTK::Inertia(m.inertia_T.x(), m.inertia_T.y(), m.inertia_T.z())));
    tibia_ = SimTK::MobilizedBody::Free(matter_.Ground(), SimTK::Transform(), body, SimTK::Transform());
    if (m.gravity_F.squaredNorm() > 0.0) {
      SimTK::Force::UniformGravity(forces_, matter_, ToVec3(m.gravity_F));
    }
    ligaments_ = new LigamentForces(forces_, tibia_, m);
    SimTK::Force::Custom(forces_, ligaments_);
    SimTK::Force::Custom(forces_, new PulseForce(tibia_, m));
    for (const ContactPair& pair : m.contacts) {
      SphereOnPlane sop;
      if (!SphereOnPlaneForm(pair, &sop)) {
        Throw<InputError>("simbody::Run", scene.path, ": the ", CompartmentName(pair.compartment),
                          " contact is not a sphere on a plane; the Simbody port models "
                          "Constraint::SphereOnPlaneContact only");
      }
      sops_.push_back(sop);
      const SimTK::UnitVec3 n_T(ToVec3(sop.normal_T));
      const SimTK::Transform plane_frame(SimTK::Rotation(n_T, SimTK::ZAxis), sop.offset * Vec3(n_T));
      contacts_.push_back(SimTK::Constraint::SphereOnPlaneContact(
          tibia_, plane_frame, matter_.updGround(), ToVec3(sop.centre_F), sop.radius,
          /*enforceRolling=*/false));
    }
    recontact_level_.assign(m.contacts.size(), 0.0);
    for (size_t i = 0; i < m.contacts.size(); ++i) {
      Add(KneeHandler::kLiftoff, static_cast<int>(i), Stage::Acceleration, false, true);
      Add(KneeHandler::kRecontact, static_cast<int>(i), Stage::Position, false, true);
    }
    if (ligaments_->locks_branches()) {
      for (size_t j = 0; j < m.ligaments.size(); ++j) {
        Add(KneeHandler::kKink, static_cast<int>(j), Stage::Position, false, true);
      }
    }
    if (scene.end.flexion) Add(KneeHandler::kEnd, 0, Stage::Position, true, false);
    system_.realizeTopology();
  }

  void Add(KneeHandler::Kind kind, int index, Stage stage, bool rising, bool falling) {
    auto* h = new KneeHandler(this, kind, index, stage);
    h->getTriggerInfo().setTriggerOnRisingSignTransition(rising);
    h->getTriggerInfo().setTriggerOnFallingSignTransition(falling);
    system_.addEventHandler(h);  // the system owns it
  }

  // JCS coordinates (α, β, γ) of R_FT (rotation.hpp's R = Rx(−α) Ry(π/2 − β) Rz(−γ)).
  static void Angles(const SimTK::Rotation& rot, double* a, double* b, double* g) {
    const SimTK::Mat33& R = rot.asMat33();
    *a = std::atan2(R(1, 2), R(2, 2));
    *b = std::atan2(std::hypot(R(1, 2), R(2, 2)), R(0, 2));
    *g = std::atan2(R(0, 1), R(0, 0));
  }
  double Flexion(const State& s) const {
    double a, b, g;
    Angles(tibia_.getBodyRotation(s), &a, &b, &g);
    return a;
  }
  bool Active(const State& s, size_t i) const { return !contacts_[i].isDisabled(s); }
  // Compressive normal force (N > 0 pushes the tibia away from the femur).
  double NormalForce(const State& s, size_t i) const {
    if (!Active(s, i)) return 0.0;
    const Vec3 n_G = tibia_.getBodyRotation(s) * ToVec3(sops_[i].normal_T);
    return ~contacts_[i].findForceOnSphereInG(s) * n_G;
  }
  double Gap(const State& s, size_t i) const { return contacts_[i].findSeparation(s); }
  double GapRate(const State& s, size_t i) const {
    const SphereOnPlane& sop = sops_[i];
    const SimTK::Rotation& R = tibia_.getBodyRotation(s);
    const Vec3 p = tibia_.getBodyOriginLocation(s), v = tibia_.getBodyOriginVelocity(s);
    const Vec3 w = tibia_.getBodyAngularVelocity(s);
    const Vec3 n = R * ToVec3(sop.normal_T);
    const Vec3 o = p + sop.offset * n;  // plane point on the tibia
    const Vec3 c = ToVec3(sop.centre_F);
    // d/dt [ n·(C − o) − r ] with ṅ = w × n, ȯ = v + w × (o − p)
    return ~(w % n) * (c - o) - ~n * (v + w % (o - p));
  }

  // Initial state: scene pose, Simbody's Assembler with the held coordinates locked, velocities
  // from the scene projected onto the constraints.
  State Assemble(InitReport* report) {
    State s = system_.getDefaultState();
    const Vector6d& q = scene_.initial.q;
    const Pose pose = PoseFromCoordinates(q);
    SimTK::Mat33 R;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) R(r, c) = pose.R_FT(r, c);
    tibia_.setQToFitTransform(s, SimTK::Transform(SimTK::Rotation(R, true), ToVec3(pose.p_FoTo_F)));
    system_.realize(s, Stage::Position);
    report->form = "simbody_assembler";
    report->position.residual_before = MaxGap(s);
    const std::vector<int>& held = scene_.initial.held;
    auto is_held = [&](int i) { return std::find(held.begin(), held.end(), i) != held.end(); };
    const int held_angles = is_held(kAlpha) + is_held(kBeta) + is_held(kGamma);
    if (held_angles != 0 && held_angles != 3) {
      Throw<InputError>("simbody::Run", scene_.path,
                        ": initial_state.hold holds some but not all of alpha, beta, gamma; the "
                        "Simbody port's free mobilizer (quaternions) can hold all three or none");
    }
    for (int i : held) report->held.push_back(CoordinateName(i));
    for (int i : scene_.initial.held_velocities) report->held.push_back(StrCat(CoordinateName(i), "_dot"));
    if (!contacts_.empty()) {
      // Simbody's Assembler: the enabled constraints as assembly errors, the held
      // coordinates locked. The Assembler works on a copy of the state in Euler angles,
      // so a Free mobilizer's q there is (three rotation angles, x, y, z).
      SimTK::Assembler assembler(system_);
      assembler.setErrorTolerance(1e-15).setAccuracy(1e-14);
      const SimTK::MobilizedBodyIndex mbx = tibia_.getMobilizedBodyIndex();
      if (held_angles == 3) {
        for (int k = 0; k < 3; ++k) assembler.lockQ(mbx, SimTK::MobilizerQIndex(k));
      }
      for (int i = kX0; i <= kZ0; ++i) {
        if (is_held(i)) assembler.lockQ(mbx, SimTK::MobilizerQIndex(3 + i));
      }
      assembler.assemble(s);  // throws (SimTK::Exception) when it cannot assemble
      report->position.iterations = assembler.getNumAssemblySteps();
    }
    system_.realize(s, Stage::Position);
    report->position.residual_after = MaxGap(s);
    // Velocities: scene q̇ → (w_G, v_G), then the velocity constraints.
    const Vector6d nu = GeneralizedVelocity(q, scene_.initial.qd);  // JCS input conversion
    tibia_.setUToFitAngularVelocity(s, tibia_.getBodyRotation(s) * ToVec3(nu.tail<3>()));
    tibia_.setUToFitLinearVelocity(s, ToVec3(nu.head<3>()));
    system_.realize(s, Stage::Velocity);
    report->velocity.residual_before = MaxGapRate(s);
    if (!contacts_.empty()) system_.projectU(s, 1e-14);
    system_.realize(s, Stage::Velocity);
    report->velocity.residual_after = MaxGapRate(s);
    InitBranches(s);
    system_.realize(s, Stage::Acceleration);
    for (size_t i = 0; i < contacts_.size(); ++i) {
      report->normal_force_guess.push_back(kNaN);
      report->normal_force.push_back(NormalForce(s, i));
    }
    DropPullingContacts(s);
    return s;
  }
  double MaxGap(const State& s) const {
    double m = 0.0;
    for (size_t i = 0; i < contacts_.size(); ++i)
      if (Active(s, i)) m = std::max(m, std::abs(Gap(s, i)));
    return m;
  }
  double MaxGapRate(const State& s) const {
    double m = 0.0;
    for (size_t i = 0; i < contacts_.size(); ++i)
      if (Active(s, i)) m = std::max(m, std::abs(GapRate(s, i)));
    return m;
  }
  void InitBranches(State& s) {
    if (!ligaments_->locks_branches()) return;
    system_.realize(s, Stage::Position);
    std::vector<int>& b = ligaments_->UpdBranches(s);
    for (size_t j = 0; j < model_.ligaments.size(); ++j) {
      b[j] = BranchByLength(model_.ligaments[j], ligaments_->Length(s, j));
    }
  }

  // Far from its kink (more than 1e-6 L0) an element's branch is decided by its length:
  // every handler re-checks, so that a crossing an integrator failed to report cannot
  // leave an element on the wrong branch past the next event.
  void ResyncBranches(State& s) {
    if (!ligaments_->locks_branches()) return;
    system_.realize(s, Stage::Position);
    const std::vector<int>& current = ligaments_->Branches(s);
    for (size_t j = 0; j < model_.ligaments.size(); ++j) {
      const Ligament& lig = model_.ligaments[j];
      const double L = ligaments_->Length(s, j);
      if (std::abs(L - KinkLength(lig)) > 1e-6 * lig.slack_length && current[j] != BranchByLength(lig, L)) {
        ligaments_->UpdBranches(s)[j] = BranchByLength(lig, L);
      }
    }
  }

  // A contact whose force would pull separates at once (the most negative first), as in
  // kneedyn's driver; each is a lift-off event.
  void DropPullingContacts(State& s) {
    for (;;) {
      system_.realize(s, Stage::Acceleration);
      int worst = -1;
      for (size_t i = 0; i < contacts_.size(); ++i) {
        if (Active(s, i) && NormalForce(s, i) < 0.0 &&
            (worst < 0 || NormalForce(s, i) < NormalForce(s, worst))) {
          worst = static_cast<int>(i);
        }
      }
      if (worst < 0) return;
      Liftoff(s, worst);
    }
  }
  void Liftoff(State& s, int i) {
    events_.push_back({StrCat("liftoff_", CompartmentName(model_.contacts[i].compartment)), s.getTime(), Flexion(s)});
    system_.realize(s, Stage::Position);
    recontact_level_[i] = std::min(Gap(s, i), 0.0) - kRecontactHysteresis;  // as kneedyn's events
    contacts_[i].disable(s);
  }

  // Perfectly plastic impact on the enabled constraints: M Δu = Gᵀ λ, G (u + Δu) = 0.
  void PlasticImpact(State& s) {
    system_.realize(s, Stage::Position);
    SimTK::Matrix G, MInv;
    matter_.calcG(s, G);
    matter_.calcMInv(s, MInv);
    const int m = G.nrow(), n = G.ncol();
    if (m == 0) return;
    Eigen::MatrixXd Ge(m, n), Mi(n, n);
    for (int r = 0; r < m; ++r)
      for (int c = 0; c < n; ++c) Ge(r, c) = G(r, c);
    for (int r = 0; r < n; ++r)
      for (int c = 0; c < n; ++c) Mi(r, c) = MInv(r, c);
    Eigen::VectorXd u(n);
    for (int k = 0; k < n; ++k) u(k) = s.getU()[k];
    const Eigen::MatrixXd A = Ge * Mi * Ge.transpose();
    const Eigen::VectorXd lambda = A.fullPivLu().solve(-Ge * u);
    const Eigen::VectorXd du = Mi * Ge.transpose() * lambda;
    for (int k = 0; k < n; ++k) s.updU()[k] += du(k);
  }
  void Project(State& s) const {
    system_.realize(s, Stage::Position);
    system_.projectQ(s, ConstraintTolerance() * 1e-2);
    system_.realize(s, Stage::Velocity);
    system_.projectU(s, ConstraintTolerance() * 1e-2);
  }
  double ConstraintTolerance() const {
    return options_.constraint_tolerance > 0.0 ? options_.constraint_tolerance : options_.accuracy;
  }

  // One output row.
  Sample MakeSample(const State& s_in, bool is_event) const {
    State s = s_in;
    system_.realize(s, Stage::Acceleration);
    Sample out;
    out.t = s.getTime();
    out.is_event = is_event;
    MechanicalState& st = out.state;
    st.t = out.t;
    const SimTK::Rotation& R = tibia_.getBodyRotation(s);
    double a, b, g;
    Angles(R, &a, &b, &g);
    const Vec3 p = tibia_.getBodyOriginLocation(s);
    st.q << p[0], p[1], p[2], a, b, g;
    Vector6d nu, nud;
    nu.head<3>() = ToEigen(tibia_.getBodyOriginVelocity(s));
    nu.tail<3>() = ToEigen(~R * tibia_.getBodyAngularVelocity(s));  // w_T = Rᵀ w_G
    nud.head<3>() = ToEigen(tibia_.getBodyOriginAcceleration(s));
    nud.tail<3>() = ToEigen(~R * tibia_.getBodyAngularAcceleration(s));  // ẇ_T = Rᵀ ẇ_G
    st.qd = CoordinateVelocity(st.q, nu);            // kneedyn kinematics: output only
    st.qdd = CoordinateAcceleration(st.q, st.qd, nud);
    st.contact.resize(contacts_.size());
    for (size_t i = 0; i < contacts_.size(); ++i) {
      const bool active = Active(s, i);
      if (active) st.active.push_back(static_cast<int>(i));
      st.contact[i].normal_force = NormalForce(s, i);
      const Vec3 c_G = contacts_[i].findContactPointInG(s);
      out.point_F.push_back(ToEigen(c_G));
      out.point_T.push_back(ToEigen(~R * (c_G - p)));
      st.contact[i].coordinates = {c_G[0], c_G[1], out.point_T.back().x(), out.point_T.back().y()};
      out.gap.push_back(Gap(s, i));
      out.gap_rate.push_back(GapRate(s, i));
    }
    out.pulse_N = PulseValue(model_.pulse, out.t);
    for (size_t j = 0; j < model_.ligaments.size(); ++j) {
      const double L = ligaments_->Length(s, j);
      out.ligament_length.push_back(L);
      out.ligament_tension.push_back(ligaments_->TensionAt(s, j, L));
    }
    out.energy = system_.calcEnergy(s);
    return out;
  }
  void Record(const State& s, bool is_event) {
    if (is_event && !samples_.empty() && samples_.back().is_event && samples_.back().t == s.getTime()) return;
    samples_.push_back(MakeSample(s, is_event));
  }

  const Scene& scene_;
  const Model& model_;
  Options options_;
  SimTK::MultibodySystem system_;
  SimTK::SimbodyMatterSubsystem matter_;
  SimTK::GeneralForceSubsystem forces_;
  SimTK::MobilizedBody::Free tibia_;
  LigamentForces* ligaments_ = nullptr;  // owned by the Force::Custom handle
  std::vector<SimTK::Constraint::SphereOnPlaneContact> contacts_;
  std::vector<SphereOnPlane> sops_;  // the pairs in closed form, parallel to contacts_
  std::vector<double> recontact_level_;  // m: gap below which a separated contact re-closes
  std::vector<EventRecord> events_;
  std::vector<Sample> samples_;
  long kink_crossings_ = 0;
  long mode_switches_ = 0;
  bool ended_on_event_ = false;
  std::string end_event_;
};

Real KneeHandler::getValue(const State& s) const {
  switch (kind_) {
    case kLiftoff:
      return knee_->Active(s, index_) ? knee_->NormalForce(s, index_) : 1.0;
    case kRecontact:
      return knee_->Active(s, index_) ? 1.0 : knee_->Gap(s, index_) - knee_->recontact_level_[index_];
    case kKink: {
      // Signed so that it is positive while the locked branch matches the length and
      // falls through zero when the element leaves its branch's region.
      const double d = knee_->ligaments_->Length(s, index_) - KinkLength(knee_->model_.ligaments[index_]);
      return knee_->ligaments_->Branches(s)[index_] == kLinear ? d : -d;
    }
    case kEnd:
      return knee_->Flexion(s) - *knee_->scene_.end.flexion;
  }
  return 1.0;
}

void KneeHandler::handleEvent(State& s, Real, bool& terminate) const {
  Knee& k = *knee_;
  switch (kind_) {
    case kKink: {
      k.system_.realize(s, Stage::Position);
      const Ligament& lig = k.model_.ligaments[index_];
      const double d = k.ligaments_->Length(s, index_) - KinkLength(lig);
      int& branch = k.ligaments_->UpdBranches(s)[index_];
      const double w = branch == kLinear ? d : -d;
      // The handler's state lies within the localization window, possibly still on the
      // old side of the kink: a witness at or below a small margin means the element is
      // crossing, so the branch toggles; well above it the report is spurious (seen with
      // CPodes) and is ignored.
      if (w <= 1e-6 * lig.slack_length) {
        branch = 1 - branch;
        ++k.kink_crossings_;
      }
      k.ResyncBranches(s);
      return;
    }
    case kEnd: {
      const double deg = RadToDeg(*k.scene_.end.flexion);
      char buf[32];
      if (std::abs(deg - std::round(deg)) < 1e-9) {
        std::snprintf(buf, sizeof(buf), "flexion_%ld", static_cast<long>(std::round(deg)));
      } else {
        std::snprintf(buf, sizeof(buf), "flexion_%.1f", deg);
      }
      k.Record(s, true);
      k.events_.push_back({buf, s.getTime(), k.Flexion(s)});
      k.ended_on_event_ = true;
      k.end_event_ = buf;
      terminate = true;
      return;
    }
    case kLiftoff: {
      if (!k.Active(s, index_)) return;
      k.Record(s, true);
      ++k.mode_switches_;
      k.Liftoff(s, index_);
      k.ResyncBranches(s);
      k.DropPullingContacts(s);
      return;
    }
    case kRecontact: {
      if (k.Active(s, index_)) return;
      k.Record(s, true);
      ++k.mode_switches_;
      k.events_.push_back({StrCat("recontact_", CompartmentName(k.model_.contacts[index_].compartment)),
                           s.getTime(), k.Flexion(s)});
      k.contacts_[index_].enable(s);
      k.PlasticImpact(s);
      k.Project(s);
      k.ResyncBranches(s);
      k.DropPullingContacts(s);
      return;
    }
  }
}

std::unique_ptr<SimTK::Integrator> MakeIntegrator(const std::string& name, const SimTK::MultibodySystem& sys,
                                                  double fixed_step) {
  using namespace SimTK;
  if (name == "rkm") return std::make_unique<RungeKuttaMersonIntegrator>(sys);
  if (name == "rk3") return std::make_unique<RungeKutta3Integrator>(sys);
  if (name == "rk2") return std::make_unique<RungeKutta2Integrator>(sys);
  if (name == "rkf") return std::make_unique<RungeKuttaFeldbergIntegrator>(sys);
  if (name == "cpodes-bdf") return std::make_unique<CPodesIntegrator>(sys, CPodes::BDF, CPodes::Newton);
  if (name == "cpodes-adams") return std::make_unique<CPodesIntegrator>(sys, CPodes::Adams, CPodes::Newton);
  if (name == "verlet") return std::make_unique<VerletIntegrator>(sys);
  if (name == "see2") return std::make_unique<SemiExplicitEuler2Integrator>(sys);
  if (name == "see") return std::make_unique<SemiExplicitEulerIntegrator>(sys, fixed_step);
  if (name == "euler") return std::make_unique<ExplicitEulerIntegrator>(sys);
  return nullptr;
}

bool NeedsFixedStep(const std::string& name) { return name == "see"; }

}  // namespace

const std::vector<std::string>& IntegratorNames() {
  static const std::vector<std::string> kNames = {"rkm", "rk3", "rk2", "rkf", "cpodes-bdf",
                                                   "cpodes-adams", "verlet", "see2", "see", "euler"};
  return kNames;
}

bool Options::IsValid(std::string* error) const {
  const auto& names = IntegratorNames();
  if (std::find(names.begin(), names.end(), integrator) == names.end()) {
    std::string list;
    for (const auto& n : names) list += (list.empty() ? "" : ", ") + n;
    *error = StrCat("--integrator = '", integrator, "': unknown; expected one of ", list);
    return false;
  }
  if (!(accuracy > 0.0 && accuracy < 1.0)) {
    *error = StrCat("--accuracy = ", accuracy, ": must be in (0, 1)");
    return false;
  }
  if (!(constraint_tolerance >= 0.0 && constraint_tolerance < 1.0)) {
    *error = StrCat("--constraint-tolerance = ", constraint_tolerance, ": must be in [0, 1) (0 = accuracy)");
    return false;
  }
  if (!(fixed_step >= 0.0 && fixed_step < 1.0)) {
    *error = StrCat("--step = ", fixed_step, " s: must be in [0, 1) (0 = adaptive)");
    return false;
  }
  if (NeedsFixedStep(integrator) && fixed_step <= 0.0) {
    *error = StrCat("--step = ", fixed_step, " s: integrator '", integrator, "' needs a fixed step > 0");
    return false;
  }
  if (!(output_interval >= 0.0)) {
    *error = StrCat("--output-interval = ", output_interval, " s: must be >= 0");
    return false;
  }
  if (max_steps <= 0) {
    *error = StrCat("--max-steps = ", max_steps, ": must be > 0");
    return false;
  }
  return true;
}

Result Run(const Scene& scene, const Options& options) {
  std::string why;
  if (!options.IsValid(&why)) Throw<InputError>("simbody::Run", why);
  // What the port does not model is refused, not dropped: its run would be another model's.
  if (scene.model.patella) {
    Throw<InputError>("simbody::Run", scene.path, ": the scene has a patella: section; the Simbody port models the "
                      "tibio-femoral joint only (the patella of docs/model.md §12 is kneedyn's)");
  }
  // kneedyn run's output grid rule (end time / interval at most 1e5 rows, interval >= 1 us).
  const double interval = options.output_interval > 0.0 ? options.output_interval : scene.output_interval;
  if (!IsValidOutputInterval(interval, scene.end.time, &why)) {
    Throw<InputError>("simbody::Run", options.output_interval > 0.0 ? "--output-interval: " : "scene output.interval_s: ",
                      why);
  }
  const auto wall_start = std::chrono::steady_clock::now();
  Knee knee(scene, options);
  Result result;
  RunResult& run = result.run;
  std::unique_ptr<SimTK::Integrator> integ;
  try {
    State s = knee.Assemble(&run.init);
    run.init.hidden.residual_after = 0.0;
    knee.Record(s, false);
    integ = MakeIntegrator(options.integrator, knee.system_, options.fixed_step);
    integ->setAccuracy(options.accuracy);
    integ->setConstraintTolerance(knee.ConstraintTolerance());
    if (options.fixed_step > 0.0 && !NeedsFixedStep(options.integrator)) integ->setFixedStepSize(options.fixed_step);
    integ->setFinalTime(scene.end.time);
    SimTK::TimeStepper ts(knee.system_, *integ);
    ts.initialize(s);
    const double dt = options.output_interval > 0.0 ? options.output_interval : scene.output_interval;
    for (long k = 1;; ++k) {
      const double t_next = std::min(k * dt, scene.end.time);
      const SimTK::Integrator::SuccessfulStepStatus status = ts.stepTo(t_next);
      if (integ->getNumStepsTaken() > options.max_steps) {
        Throw<SolverError>("simbody::Run", "more than --max-steps = ", options.max_steps,
                           " steps at t = ", integ->getTime(), " s");
      }
      if (integ->isSimulationOver() && knee.ended_on_event_) break;
      if (status == SimTK::Integrator::ReachedReportTime ||
          (status == SimTK::Integrator::EndOfSimulation && integ->getTime() >= scene.end.time)) {
        // An output time on an event row is skipped (times strictly increasing).
        if (!(knee.samples_.back().is_event && std::abs(knee.samples_.back().t - integ->getTime()) < 1e-12)) {
          knee.Record(integ->getState(), false);
        }
      }
      if (integ->isSimulationOver() || t_next >= scene.end.time) {
        if (integ->isSimulationOver() && integ->getTerminationReason() != SimTK::Integrator::ReachedFinalTime &&
            !knee.ended_on_event_) {
          Throw<SolverError>("simbody::Run", "Simbody integrator stopped at t = ", integ->getTime(),
                             " s: ", SimTK::Integrator::getTerminationReasonString(integ->getTerminationReason()));
        }
        break;
      }
    }
    run.completed = true;
    run.end_reason = knee.ended_on_event_ ? knee.end_event_ : "end_time";
  } catch (const InputError&) {
    throw;
  } catch (const std::exception& e) {
    run.completed = false;
    run.failure = e.what();
  }
  if (integ) {
    SolverStats& st = run.stats;
    st.steps = integ->getNumStepsTaken();
    st.residual_evaluations = integ->getNumRealizations();
    st.error_test_failures = integ->getNumErrorTestFailures();
    st.convergence_failures = integ->getNumConvergenceTestFailures();
    st.nonlinear_iterations = integ->getNumIterations();
    st.projections = integ->getNumProjections();
    st.restarts = 1 + knee.mode_switches_ + knee.kink_crossings_;
  }
  run.ligament_kink_crossings = knee.kink_crossings_;
  run.events = knee.events_;
  for (const Sample& smp : knee.samples_) {
    run.samples.push_back(smp.state);
    run.sample_is_event.push_back(smp.is_event);
    for (int i : smp.state.active) {
      run.max_position_residual = std::max(run.max_position_residual, std::abs(smp.gap[i]));
      run.max_velocity_residual = std::max(run.max_velocity_residual, std::abs(smp.gap_rate[i]));
    }
  }
  if (!run.samples.empty()) run.init.hidden.residual_after = 0.0;
  result.samples = std::move(knee.samples_);
  run.wall_time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  return result;
}

// ---------------------------------------------------------------------------------------
// Output files: the columns of formulations/run_output.cpp, values from the samples.

namespace {

// "ACL anterior" -> "ACL_anterior" (column names as formulations/run_output.cpp).
std::string ColumnSafeName(const std::string& name) {
  std::string out = name;
  for (char& c : out) {
    if (c == ' ' || c == '-' || c == '/') c = '_';
  }
  return out;
}

std::string Format(double v) {
  if (!std::isfinite(v)) return "";
  char buf[40];
  std::snprintf(buf, sizeof(buf), "%.12g", v);
  return buf;
}

void WriteAtomically(const std::filesystem::path& dir, const std::string& name, const std::string& text) {
  const std::filesystem::path tmp = dir / ("." + name + ".tmp");
  {
    std::ofstream out(tmp);
    if (!out) Throw<InputError>("simbody::WriteOutputs", "cannot write '", tmp.string(), "'");
    out << text;
    if (!out) {
      out.close();
      std::filesystem::remove(tmp);
      Throw<InputError>("simbody::WriteOutputs", "failed writing '", tmp.string(), "'");
    }
  }
  std::filesystem::rename(tmp, dir / name);
}

}  // namespace

void WriteOutputs(const std::string& dir_name, const Scene& scene, const Options& options,
                  const Result& result) {
  const Model& model = scene.model;
  namespace fs = std::filesystem;
  const fs::path dir(dir_name);
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir)) {
    Throw<InputError>("simbody::WriteOutputs", "--out = '", dir_name, "': cannot create directory (",
                      ec.message(), ")");
  }
  std::vector<std::string> cols = {
      "time_s", "flexion_deg", "valgus_deg", "external_rotation_deg", "x0_mm", "y0_mm", "z0_mm",
      "vx_mm_s", "vy_mm_s", "vz_mm_s", "flexion_rate_deg_s", "valgus_rate_deg_s",
      "external_rotation_rate_deg_s", "omega_x_T_deg_s", "omega_y_T_deg_s", "omega_z_T_deg_s",
      "pulse_N", "contacts_active", "is_event"};
  // One group per contact pair of the model, in model order, as kneedyn's trajectory.csv
  // (formulations/run_output.cpp, MakeTrajectoryTable): a scene without contacts has none.
  std::vector<std::string> comps;
  for (const ContactPair& pair : model.contacts) comps.push_back(CompartmentName(pair.compartment));
  for (const std::string& c : comps)
    for (const char* frame : {"femoral", "tibial"})
      for (const char* axis : {"x", "y", "z"}) cols.push_back(StrCat(frame, "_", c, "_", axis, "_mm"));
  for (const std::string& c : comps) cols.push_back(StrCat("N_", c, "_N"));
  for (const Ligament& lig : model.ligaments) cols.push_back("F_" + ColumnSafeName(lig.name) + "_N");
  for (const std::string& c : comps) cols.push_back(StrCat("gap_", c, "_mm"));
  for (const std::string& c : comps) cols.push_back(StrCat("gap_rate_", c, "_mm_s"));
  for (const Ligament& lig : model.ligaments) cols.push_back("L_" + ColumnSafeName(lig.name) + "_mm");
  for (const Ligament& lig : model.ligaments) cols.push_back("strain_" + ColumnSafeName(lig.name));

  std::vector<std::vector<double>> rows;
  for (const Sample& smp : result.samples) {
    const MechanicalState& st = smp.state;
    const Vector6d& q = st.q;
    const Vector6d& qd = st.qd;
    std::vector<double> row = {smp.t, RadToDeg(q(kAlpha)), RadToDeg(q(kBeta)) - 90.0, RadToDeg(q(kGamma)),
                               MToMm(q(kX0)), MToMm(q(kY0)), MToMm(q(kZ0)), MToMm(qd(kX0)), MToMm(qd(kY0)),
                               MToMm(qd(kZ0)), RadToDeg(qd(kAlpha)), RadToDeg(qd(kBeta)), RadToDeg(qd(kGamma))};
    const Vector3d w = AngularVelocityT(q, qd);
    for (int i = 0; i < 3; ++i) row.push_back(RadToDeg(w(i)));
    row.push_back(smp.pulse_N);
    row.push_back(static_cast<double>(st.active.size()));
    row.push_back(smp.is_event ? 1.0 : 0.0);
    const int n_contacts = static_cast<int>(model.contacts.size());
    for (int idx = 0; idx < n_contacts; ++idx) {
      if (st.IsActive(idx)) {
        for (int a = 0; a < 3; ++a) row.push_back(MToMm(smp.point_F[idx](a)));
        for (int a = 0; a < 3; ++a) row.push_back(MToMm(smp.point_T[idx](a)));
      } else {
        row.insert(row.end(), 6, kNaN);
      }
    }
    for (int idx = 0; idx < n_contacts; ++idx) row.push_back(st.IsActive(idx) ? st.contact[idx].normal_force : 0.0);
    for (double f : smp.ligament_tension) row.push_back(f);
    for (int idx = 0; idx < n_contacts; ++idx) row.push_back(MToMm(smp.gap[idx]));
    for (int idx = 0; idx < n_contacts; ++idx) row.push_back(MToMm(smp.gap_rate[idx]));
    for (double L : smp.ligament_length) row.push_back(MToMm(L));
    for (size_t j = 0; j < model.ligaments.size(); ++j) {
      row.push_back((smp.ligament_length[j] - model.ligaments[j].slack_length) / model.ligaments[j].slack_length);
    }
    rows.push_back(std::move(row));
  }
  std::ostringstream csv, sto;
  for (size_t c = 0; c < cols.size(); ++c) csv << (c ? "," : "") << cols[c];
  csv << "\n";
  sto << "kneedyn_" << scene.name << "\nversion=1\nnRows=" << rows.size() << "\nnColumns=" << cols.size()
      << "\ninDegrees=yes\n"
      << "// lengths in mm, forces in N, angles in deg; engine Simbody " << options.integrator
      << (result.run.completed ? "" : "; PARTIAL: solver failed") << "\nendheader\n";
  for (size_t c = 0; c < cols.size(); ++c) sto << (c ? "\t" : "") << (c == 0 ? std::string("time") : cols[c]);
  sto << "\n";
  for (const auto& row : rows) {
    for (size_t c = 0; c < row.size(); ++c) {
      csv << (c ? "," : "") << Format(row[c]);
      sto << (c ? "\t" : "") << (std::isfinite(row[c]) ? Format(row[c]) : "NaN");
    }
    csv << "\n";
    sto << "\n";
  }
  // summary.json: the fields of `kneedyn run`'s summary (formulations/run_output.cpp),
  // written here so that this program links no SUNDIALS (see CMakeLists.txt), plus the
  // engine's own settings.
  const RunResult& run = result.run;
  nlohmann::json j;
  j["kneedyn_version"] = "0.1.0";
  j["status"] = run.completed ? "completed" : "partial";
  if (!run.completed) j["failure"] = run.failure;
  j["end_reason"] = run.end_reason;
  j["scene"] = {{"name", scene.name}, {"path", scene.path}, {"parameter_set", scene.parameter_set},
                {"ligaments", model.ligaments.size()}, {"contacts", model.contacts.size()},
                {"pulse", {{"shape", PulseShapeName(model.pulse.shape)},
                           {"amplitude_N", model.pulse.amplitude}, {"duration_s", model.pulse.duration},
                           {"peak_factor", PulsePeakFactor(model.pulse.shape)}}},
                {"ligament_law", LigamentLawName(model.ligament_law)}};
  const double cons_tol = options.constraint_tolerance > 0 ? options.constraint_tolerance : options.accuracy;
  j["formulation"] = "simbody";
  j["settings"] = {{"rtol", options.accuracy}, {"atol", cons_tol}, {"integrator", options.integrator},
                   {"step_s", options.fixed_step}, {"max_step_s", 0.0},
                   {"stabilization", "simbody-projection"}, {"constraint_level", "position"},
                   {"output_interval_s", options.output_interval > 0 ? options.output_interval : scene.output_interval}};
  auto level = [](const InitLevelReport& r) {
    return nlohmann::json{{"residual_before", r.residual_before}, {"residual_after", r.residual_after},
                          {"iterations", r.iterations}};
  };
  nlohmann::json guess = nlohmann::json::object(), force = nlohmann::json::object();
  for (size_t i = 0; i < model.contacts.size() && i < run.init.normal_force.size(); ++i) {
    guess[CompartmentName(model.contacts[i].compartment)] = nullptr;  // no guesses: multipliers
    force[CompartmentName(model.contacts[i].compartment)] = run.init.normal_force[i];
  }
  j["initialization"] = {{"form", run.init.form}, {"held", run.init.held},
                         {"position", level(run.init.position)}, {"velocity", level(run.init.velocity)},
                         {"hidden_constraint", level(run.init.hidden)},
                         {"normal_force_guess_N", guess}, {"normal_force_N", force}};
  nlohmann::json events = nlohmann::json::array();
  for (const EventRecord& e : run.events) {
    events.push_back({{"name", e.name}, {"time", e.time}, {"flexion_deg", RadToDeg(e.flexion)}});
  }
  j["events"] = events;
  if (!result.samples.empty()) {
    const MechanicalState& st = result.samples.back().state;
    nlohmann::json f;
    f["time_s"] = st.t;
    f["flexion_deg"] = RadToDeg(st.q(kAlpha));
    f["valgus_deg"] = RadToDeg(st.q(kBeta)) - 90.0;
    f["external_rotation_deg"] = RadToDeg(st.q(kGamma));
    f["R0_mm"] = {MToMm(st.q(0)), MToMm(st.q(1)), MToMm(st.q(2))};
    f["v_mm_s"] = {MToMm(st.qd(0)), MToMm(st.qd(1)), MToMm(st.qd(2))};
    f["angle_rates_deg_s"] = {RadToDeg(st.qd(3)), RadToDeg(st.qd(4)), RadToDeg(st.qd(5))};
    nlohmann::json contacts = nlohmann::json::object();
    for (size_t i = 0; i < model.contacts.size(); ++i) {
      const bool active = st.IsActive(static_cast<int>(i));
      contacts[CompartmentName(model.contacts[i].compartment)] = {
          {"active", active}, {"normal_force_N", active ? st.contact[i].normal_force : 0.0}};
    }
    f["contacts"] = contacts;
    j["final_state"] = f;
  }
  const SolverStats& st = run.stats;
  j["statistics"] = {{"steps", st.steps}, {"residual_evaluations", st.residual_evaluations},
                     {"jacobian_evaluations", st.jacobian_evaluations},
                     {"linear_solver_setups", st.linear_solver_setups},
                     {"nonlinear_iterations", st.nonlinear_iterations},
                     {"error_test_failures", st.error_test_failures},
                     {"convergence_failures", st.convergence_failures}, {"step_halvings", st.step_halvings},
                     {"rejected_steps", st.error_test_failures + st.convergence_failures + st.step_halvings},
                     {"root_evaluations", st.root_evaluations}, {"projections", st.projections},
                     {"restarts", st.restarts}, {"ligament_kink_crossings", run.ligament_kink_crossings}};
  j["constraint_residuals"] = {{"max_gap_mm", MToMm(run.max_position_residual)},
                               {"max_gap_rate_mm_s", MToMm(run.max_velocity_residual)}};
  j["wall_time_s"] = run.wall_time_s;
  j["versions"] = {{"ceres", CERES_VERSION_STRING},  // scene loading only; no SUNDIALS linked
                   {"eigen", StrCat(EIGEN_WORLD_VERSION, ".", EIGEN_MAJOR_VERSION, ".", EIGEN_MINOR_VERSION)}};
  j["engine"] = {{"name", "simbody"},
                 {"version", KNEEDYN_SIMBODY_VERSION},
                 {"integrator", options.integrator},
                 {"accuracy", options.accuracy},
                 {"constraint_tolerance", cons_tol},
                 {"fixed_step_s", options.fixed_step}};
  j["versions"]["simbody"] = j["engine"]["version"];
  j["energy_drift_relative"] = EnergyDrift(result);
  WriteAtomically(dir, "trajectory.csv", csv.str());
  WriteAtomically(dir, "trajectory.sto", sto.str());
  WriteAtomically(dir, "summary.json", j.dump(2) + "\n");
}

double EnergyDrift(const Result& result) {
  if (result.samples.empty()) return kNaN;
  const double e0 = result.samples.front().energy;
  double worst = 0.0;
  for (const Sample& smp : result.samples) worst = std::max(worst, std::abs(smp.energy - e0));
  return worst / std::abs(e0);
}

}  // namespace simbody
}  // namespace kneedyn
