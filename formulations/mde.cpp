// `mde`: minimal differential equations. The contact conditions φ_i(q) = 0
// (contact_kinematics.hpp, any surface pair) are solved for k translations of R0 by Newton
// (∂φ_i/∂R0 = −n_F,i; for sphere on plane φ_i = n_i·(C_i − R0) − d_i − r_i is linear in R0
// and one step is exact), so k active contacts eliminate k translations and the state is
// y = (s, ṡ) with the 6 − k free coordinates s:
//   two-point  s = (y0, α, β, γ): x0, z0 from the 2×2 solve of φ1 = φ2 = 0 (the admissible
//              R0 lie on a line along n1 × n2, parameterised by y0);
//   one-point  s = (x0, y0, α, β, γ): z0 from φ = 0;
//   none       s = q.
// (The eliminated pair/component is the one with the best-conditioned solve at the phase
// start, x0, z0 resp. z0 at the chapter's start poses; after every accepted step the chart
// is switched — integrator restart — when another choice is better conditioned by 2x. A
// chart that lost a factor kMaxChartDegradation within one step is refused with a
// SolverError: the elimination would silently return garbage, e.g. z0 of a one-point
// contact as its normal turns horizontal near 90° flexion.)
// Velocities by the chain rule: φ̇ = J q̇ = 0 with J = ∂φ/∂q = G B (contact.hpp, pose.hpp)
// gives q̇ = P ṡ, P = [I; −J_D⁻¹ J_F] (D eliminated, F free columns).
// Accelerations without second derivatives of the elimination: φ̈ = G ν̇ + κ = 0 with
// ν̇ = B q̈ + (0, Ė θ̇) gives J q̈ + c = 0, c = G_w Ė θ̇ + κ, so q̈ = P s̈ + p with
// p_D = −J_D⁻¹ c, and ν̇ = A s̈ + b with A = B P, b = B p + (0, Ė θ̇). Projecting the
// Newton–Euler equations M ν̇ = Q + Σ N_i G_iᵀ onto the admissible motions (G A = J P = 0):
//   (Aᵀ M A) s̈ = Aᵀ (Q − M b)                                 (Kane / Maggi form)
// Contact forces afterwards from the full equations: Gᵀ N = M ν̇ − Q (least squares).
// The constraints hold by construction (no drift); lift-off root g = N_i.
#include <Eigen/LU>
#include <array>
#include <cstring>
#include <algorithm>
#include <Eigen/QR>
#include <cmath>
#include <memory>

#include "formulations/internal/formulation_base.hpp"
#include "formulations/internal/ode_integrator.hpp"
#include "solver/consistent_init.hpp"
#include "solver/constrained_dynamics.hpp"
#include "solver/units.hpp"

namespace kneedyn {
namespace {

// |det| of the elimination solve below which the pose is treated as degenerate.
constexpr double kMinEliminationDeterminant = 1.0e-8;
// Largest loss of conditioning of the chart in use, best |det| / its |det|, tolerated
// inside a step (charts are switched at 2x after each step).
constexpr double kMaxChartDegradation = 1.0e3;
// Newton for the eliminated translations: stop at this max |φ_i| (m) / after this many steps.
constexpr double kEliminationTolerance = 1.0e-15;
constexpr int kMaxEliminationIterations = 20;

// Fixed-capacity Eigen types of the elimination (k ≤ 2 active contacts, m = 6 − k ≤ 6 free
// coordinates): no heap allocation in the right-hand side (tests/zero_allocation_test.cpp).
constexpr int kMaxMdeContacts = 2;
using MatKK = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxMdeContacts, kMaxMdeContacts>;
using MatK3 = Eigen::Matrix<double, Eigen::Dynamic, 3, 0, kMaxMdeContacts, 3>;
using MatK6 = Eigen::Matrix<double, Eigen::Dynamic, 6, 0, kMaxMdeContacts, 6>;
using MatKM = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxMdeContacts, 6>;
using Mat6M = Eigen::Matrix<double, 6, Eigen::Dynamic, 0, 6, 6>;
using Mat6K = Eigen::Matrix<double, 6, Eigen::Dynamic, 0, 6, kMaxMdeContacts>;
using MatMM = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 6, 6>;
using VecK = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxMdeContacts, 1>;
using VecM = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 6, 1>;

struct MdeKinematics {
  Vector6d q, qd, qdd;
  std::array<double, kMaxMdeContacts> normal_force{};  // per active contact, N
};

class MdeFormulation final : public FormulationBase, public OdeProblem {
 public:
  MdeFormulation(const Scene& scene, const OdeOptions& options)
      : FormulationBase(scene), options_(options), integrator_(options, "mde"),
        data_(model_) {
    normal_.assign(model_.contacts.size(), 0.0);
  }

  ContactForm contact_form() const override { return ContactForm::kClosedForm; }

  void Start(const MechanicalState& state, const std::vector<EventSpec>& events) override {
    BeginPhase(state, events);
    elim_.clear();
    phase_steps_ = 0;
    last_q_ = state.q;
    ChooseEliminated(state.q);
    StartIntegrator(state);
  }

  // (Re)starts the integrator from a state in the current chart.
  void StartIntegrator(const MechanicalState& state) {
    const int m = static_cast<int>(free_.size());
    y_.resize(2 * m);
    for (int j = 0; j < m; ++j) {
      y_(j) = state.q(free_[j]);
      y_(m + j) = state.qd(free_[j]);
    }
    t_ = state.t;
    cache_valid_ = false;  // new chart, start point or phase
    const std::vector<int> dirs = RootDirections(events_);
    integrator_.Start(this, t_, y_, dirs);
  }

  AdvanceResult Advance(double t_out, MechanicalState* state) override {
    std::vector<int> found;
    bool root = false;
    do {
      // One step at a time: the chart is checked after every step, not only at output
      // times (whose spacing must not change the physics).
      root = integrator_.Evolve(t_out, true, &t_, &y_, &found);
      if (++phase_steps_ > options_.control.max_steps) {  // the budget ARKODE applies per call only
        Throw<SolverError>("MdeFormulation::Advance", "more than --max-steps = ", options_.control.max_steps,
                           " steps in this contact phase at t = ", t_, " s");
      }
      if (!root && !active_.empty()) SwitchChartIfBetter();
    } while (!root && t_ < t_out);
    const MdeKinematics kin = Evaluate(t_, y_.data(), nullptr);
    WriteBack(t_, kin.q, kin.qd, kin.qdd, kin.normal_force.data(), nullptr, 0, state);
    return root ? EventResult(found) : AdvanceResult{};
  }

  // y = (s, ṡ), s the free coordinates of the phase: "alpha", "alpha_rate", ...
  std::string StateName(int i) const override {
    const int m = static_cast<int>(free_.size());
    return i < m ? std::string(CoordinateName(free_[i])) : std::string(CoordinateName(free_[i - m])) + "_rate";
  }

  // The OdeIntegrator lives across phases and counts over the whole run.
  SolverStats PhaseStats() const override { return integrator_.stats(); }
  std::string integrator() const override { return integrator_.name(); }
  bool EvaluateHotPathForTesting(int n) override { return integrator_.EvaluateCallbacksForTesting(t_, y_, n); }
  double fixed_step() const override { return integrator_.step(); }

  bool Rhs(double t, const double* y, double* ydot) override {
    const int m = static_cast<int>(free_.size());
    VecM sdd(m);
    Evaluate(t, y, &sdd);
    for (int j = 0; j < m; ++j) {
      ydot[j] = y[m + j];
      ydot[m + j] = sdd(j);
    }
    return true;
  }

  void Roots(double t, const double* y, double* g) override {
    const MdeKinematics kin = Evaluate(t, y, nullptr);
    std::fill(normal_.begin(), normal_.end(), 0.0);
    for (size_t c = 0; c < active_.size(); ++c) normal_[active_[c]] = kin.normal_force[c];
    EvaluateEvents(scene_.model, events_, kin.q, normal_, g);
  }

 private:
  // After an accepted step: restart in a better chart when the one in use lost a factor 2.
  void SwitchChartIfBetter() {
    const std::vector<int> before = elim_;
    // The new chart's state from the full q, q̇ of the old one (exact: same point).
    const MdeKinematics kin = Evaluate(t_, y_.data(), nullptr);
    ChooseEliminated(kin.q);
    if (elim_ == before) return;
    last_q_ = kin.q;
    MechanicalState at;
    at.t = t_;
    at.q = kin.q;
    at.qd = kin.qd;
    StartIntegrator(at);
  }

  void SetFree() {
    free_.clear();
    for (int i = 0; i < 6; ++i) {
      if (std::find(elim_.begin(), elim_.end(), i) == elim_.end()) free_.push_back(i);
    }
  }

  // Candidate eliminated sets for k active contacts, in the documented order.
  static const std::vector<std::vector<int>>& Candidates(int k) {
    static const std::vector<std::vector<int>> kNone = {{}};
    static const std::vector<std::vector<int>> kOne = {{kZ0}, {kX0}, {kY0}};
    static const std::vector<std::vector<int>> kTwo = {{kX0, kZ0}, {kY0, kZ0}, {kX0, kY0}};
    return k == 0 ? kNone : k == 1 ? kOne : kTwo;
  }

  // |det| of the elimination block of `cand` for the normals n_i = R n̂′_i (rows).
  static double BlockDeterminant(const MatK3& normals, const std::vector<int>& cand) {
    const int k = static_cast<int>(cand.size());
    if (k == 0) return 1.0;
    MatKK block(k, k);
    for (int c = 0; c < k; ++c) block.col(c) = normals.col(cand[c]);
    return std::abs(block.determinant());
  }

  // Contact normals n_F (rows) of the active contacts at the full pose q.
  MatK3 ContactNormals(const Vector6d& q) const {
    const int k = static_cast<int>(active_.size());
    const Pose pose = PoseFromCoordinates(q);
    MatK3 normals(k, 3);
    for (int r = 0; r < k; ++r) {
      const ContactGeometry g = RequireContactKinematics(model_.contacts[active_[r]], pose, "MdeFormulation");
      normals.row(r) = (pose.R_FT * g.normal_T).transpose();
    }
    return normals;
  }

  // Picks the k translations to eliminate: the best-conditioned k×k block of the normals.
  void ChooseEliminated(const Vector6d& q) {
    const int k = static_cast<int>(active_.size());
    if (k > 2) Throw<SolverError>("MdeFormulation::Start", k, " active contacts; at most 2 supported");
    const MatK3 normals = ContactNormals(q);
    const std::vector<int> current = elim_;
    double current_det = -1.0;
    elim_.clear();
    double best = -1.0;
    for (const std::vector<int>& cand : Candidates(k)) {
      const double det = BlockDeterminant(normals, cand);
      if (cand == current) current_det = det;
      if (det > best * 1.5) {  // keep the documented order unless clearly worse
        best = det;
        elim_ = cand;
      }
    }
    // Keep the chart in use while it stays within a factor 2 of the best one.
    if (!current.empty() && current.size() == static_cast<size_t>(k) && current_det >= 0.5 * best) {
      elim_ = current;
      best = current_det;
    }
    if (best < kMinEliminationDeterminant) {
      Throw<SolverError>("MdeFormulation::Start", "contact normals are (nearly) dependent: |det| = ", best);
    }
    SetFree();
  }

  // q from s (closed-form elimination); qd = P ṡ; s̈ (if sdd) and q̈, N.
  // Returns the last result when (t, y) are bitwise those of the previous call in this
  // chart: the root functions at a step's end, the chart check after the step and the
  // first stage of the next (FSAL of the Dormand–Prince pair) ask for the same point.
  MdeKinematics Evaluate(double t, const double* y, VecM* sdd_out) const {
    const int m = static_cast<int>(free_.size());
    if (cache_valid_ && t == cache_t_ && std::memcmp(y, cache_y_.data(), sizeof(double) * 2 * m) == 0) {
      if (sdd_out) *sdd_out = cache_sdd_;
      return cache_kin_;
    }
    cache_valid_ = false;  // a throwing evaluation leaves no stale entry
    const MdeKinematics kin = EvaluateUncached(t, y, &cache_sdd_);
    if (sdd_out) *sdd_out = cache_sdd_;
    cache_t_ = t;
    std::memcpy(cache_y_.data(), y, sizeof(double) * 2 * m);
    cache_kin_ = kin;
    cache_valid_ = true;
    return kin;
  }

  MdeKinematics EvaluateUncached(double t, const double* y, VecM* sdd_out) const {
    const int m = static_cast<int>(free_.size());
    const int k = static_cast<int>(elim_.size());
    MdeKinematics kin;
    kin.q = last_q_;
    for (int j = 0; j < m; ++j) kin.q(free_[j]) = y[j];
    // φ_i(q) = 0 solved for the eliminated translations by Newton (∂φ_i/∂R0 = −n_F,i); one
    // step is exact for a sphere on a plane (φ linear in R0), a few for curved surfaces.
    std::array<ContactGeometry, kMaxMdeContacts> geo;
    // Closed form where one exists: n_i · R0 = n_i · C_i − d_i − r_i (linear in R0).
    bool closed_form = k > 0;
    std::array<SphereOnPlane, kMaxMdeContacts> sop;
    for (int r = 0; r < k; ++r) closed_form = closed_form && SphereOnPlaneForm(model_.contacts[active_[r]], &sop[r]);
    if (closed_form) {
      const Matrix3d R = RotationFT(kin.q(kAlpha), kin.q(kBeta), kin.q(kGamma));
      MatKK ND(k, k);
      VecK rhs(k);
      for (int r = 0; r < k; ++r) {
        const Vector3d n = R * sop[r].normal_T;
        rhs(r) = n.dot(sop[r].centre_F) - sop[r].offset - sop[r].radius;
        for (int j = 0; j < m; ++j) {
          if (free_[j] < 3) rhs(r) -= n(free_[j]) * kin.q(free_[j]);
        }
        for (int c = 0; c < k; ++c) ND(r, c) = n(elim_[c]);
      }
      const VecK x = ND.partialPivLu().solve(rhs);
      for (int c = 0; c < k; ++c) kin.q(elim_[c]) = x(c);
      const Pose pose_c = PoseFromCoordinates(kin.q);
      for (int r = 0; r < k; ++r) geo[r] = SphereOnPlaneContact(sop[r], pose_c);
    }
    for (int iter = 0; k > 0 && !closed_form; ++iter) {
      const Pose pose_i = PoseFromCoordinates(kin.q);
      MatKK ND(k, k);
      VecK phi(k);
      for (int r = 0; r < k; ++r) {
        geo[r] = RequireContactKinematics(model_.contacts[active_[r]], pose_i, "MdeFormulation::Evaluate");
        phi(r) = geo[r].gap;
        const Vector3d n = pose_i.R_FT * geo[r].normal_T;
        for (int c = 0; c < k; ++c) ND(r, c) = -n(elim_[c]);
      }
      // At least one step: the result must not depend on the start (last_q_).
      if (iter > 0 && phi.cwiseAbs().maxCoeff() <= kEliminationTolerance) break;
      if (iter == kMaxEliminationIterations) {
        Throw<SolverError>("MdeFormulation::Evaluate", "eliminating the contact translations did not converge at t = ", t,
                           " s: max |gap| = ", phi.cwiseAbs().maxCoeff(), " m after ", iter,
                           " Newton steps (rule: <= ", kEliminationTolerance, " m)");
      }
      const VecK dx = ND.partialPivLu().solve(phi);
      for (int c = 0; c < k; ++c) kin.q(elim_[c]) -= dx(c);
    }
    const EulerAngleTrig<double> trig = EulerAngleTrigOf(kin.q);  // of the final pose (rotation.hpp)
    if (k > 0) {
      // The chart in use must still be usable here (see kMaxChartDegradation). geo[r] is the
      // contact at kin.q already (the elimination stops before updating q), so the normals
      // come from it instead of another k local contact solves (perf: a third of the
      // right-hand side's time on general surfaces).
      MatK3 normals(k, 3);
      const Matrix3d R_FT = RotationFT(trig);
      for (int r = 0; r < k; ++r) normals.row(r) = (R_FT * geo[r].normal_T).transpose();
      double best = 0.0;
      for (const std::vector<int>& cand : Candidates(k)) best = std::max(best, BlockDeterminant(normals, cand));
      const double det = BlockDeterminant(normals, elim_);
      if (!(det * kMaxChartDegradation >= best)) {
        Throw<SolverError>("MdeFormulation::Evaluate", "the eliminated coordinates became ill-conditioned within one step at t = ", t,
                           " s, flexion = ", RadToDeg(kin.q(kAlpha)), " deg: |det| = ", det,
                           " of the eliminated block vs ", best, " of the best one (rule: within a factor ",
                           kMaxChartDegradation, "; reduce --rtol or --max-step)");
      }
    }
    const Pose pose = PoseFromCoordinates(kin.q, trig);
    const Matrix3d E = AngularVelocityMap(kin.q(kBeta), trig);
    // J = ∂φ/∂q = G B, and P = ∂q/∂s.
    MatK6 J(k, 6), G(k, 6);
    for (int r = 0; r < k; ++r) {
      G.row(r) = ContactConstraintRow(pose, geo[r]);
      J.block(r, 0, 1, 3) = G.block(r, 0, 1, 3);
      J.block(r, 3, 1, 3) = G.block(r, 3, 1, 3) * E;
    }
    Mat6M P = Mat6M::Zero(6, m);
    for (int j = 0; j < m; ++j) P(free_[j], j) = 1.0;
    Eigen::PartialPivLU<MatKK> JD_lu;
    if (k > 0) {
      MatKK JD(k, k);
      MatKM JF(k, m);
      for (int c = 0; c < k; ++c) JD.col(c) = J.col(elim_[c]);
      for (int j = 0; j < m; ++j) JF.col(j) = J.col(free_[j]);
      JD_lu.compute(JD);
      const MatKM PD = -JD_lu.solve(JF);
      for (int c = 0; c < k; ++c) P.row(elim_[c]) = PD.row(c);
    }
    const VecM sd = Eigen::Map<const VectorXd>(y + m, m);
    kin.qd = P * sd;
    const Vector6d nu = GeneralizedVelocity(kin.q, trig, kin.qd);
    const Vector3d qd_ang = kin.qd.tail<3>();
    const Vector3d Edot_thetadot = AngularVelocityMapRateTimesRate(trig, qd_ang);
    // q̈ = P s̈ + p;  c_i = G_w,i Ė θ̇ + κ_i.
    Vector6d p = Vector6d::Zero();
    if (k > 0) {
      VecK c(k);
      for (int r = 0; r < k; ++r) {
        c(r) = (G.block(r, 3, 1, 3) * Edot_thetadot)(0) +
               ContactRateTerm(model_.contacts[active_[r]], kin.q, kin.qd, pose, nu);
      }
      const VecK pD = -JD_lu.solve(c);
      for (int r = 0; r < k; ++r) p(elim_[r]) = pD(r);
    }
    // ν̇ = A s̈ + b.
    Mat6M A(6, m);
    A.topRows(3) = P.topRows(3);
    A.bottomRows(3) = E * P.bottomRows(3);
    Vector6d b;
    b.head<3>() = p.head<3>();
    b.tail<3>() = E * p.tail<3>() + Edot_thetadot;
    Data& data = data_;
    data.ligament_branch = &ligament_branch_;
    ComputeAppliedWrench(model_, t, pose, &data);
    const Vector6d Q = GeneralizedForce(model_, data, Vector3d(nu.tail<3>()));
    const Matrix6d M = MassMatrix(model_);
    const MatMM AtMA = A.transpose() * M * A;
    const VecM sdd = AtMA.ldlt().solve(A.transpose() * (Q - M * b));
    if (sdd_out) *sdd_out = sdd;
    kin.qdd = P * sdd + p;
    // Gᵀ N = M ν̇ − Q.
    if (k > 0) {
      const Vector6d residual = M * (A * sdd + b) - Q;
      const Mat6K Gt = G.transpose();
      const VecK N = Gt.colPivHouseholderQr().solve(residual);
      for (int c = 0; c < k; ++c) kin.normal_force[c] = N(c);
    }
    return kin;
  }

  OdeOptions options_;
  OdeIntegrator integrator_;
  double t_ = 0.0;
  VectorXd y_;
  std::vector<int> free_;  // indices into q of s, ascending
  std::vector<int> elim_;  // eliminated translations (one per active contact)
  long phase_steps_ = 0;
  // The eliminated translations start Newton from the phase start's values, so that the
  // right-hand side is a function of (t, y) alone (no dependence on the call history).
  Vector6d last_q_ = Vector6d::Zero();   // steps since Start (the --max-steps budget is per phase)
  mutable Data data_;           // applied-load workspace of Evaluate
  // Evaluate's last result and its (t, y) (2 m ≤ 12 values; reset by StartIntegrator).
  mutable bool cache_valid_ = false;
  mutable double cache_t_ = 0.0;
  mutable std::array<double, 12> cache_y_{};
  mutable MdeKinematics cache_kin_;
  mutable VecM cache_sdd_;
  std::vector<double> normal_;  // N per model contact, for the root functions
};

}  // namespace

FormulationMaker ConfigureMde(const OptionRequest& request) {
  OdeOptions options;
  if (!ReadOdeOptions(request, &options)) return nullptr;
  return [options](const Scene& scene) { return std::make_unique<MdeFormulation>(scene, options); };
}

}  // namespace kneedyn
