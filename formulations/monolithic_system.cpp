#include "formulations/internal/monolithic_system.hpp"

#include <algorithm>

#include <Eigen/LU>

#include "solver/events.hpp"
#include "solver/newton_euler_jacobian.hpp"

namespace kneedyn {
namespace {

// Derivative slots of the coupling blocks: 0–5 the tibial coordinates q, 6–22 the patella x.
constexpr int kCouplingJetSize = 6 + kPatellaUnknowns;
using CouplingJet = ceres::Jet<double, kCouplingJetSize>;

// The coupling rows as Jets over (q, x) at (q, x) = (y[0, 6), y[n_t, n_t + 17)).
bool LinearizeCoupling(const Patella& patella, const PatellaFacets& pressing, double t, const double* y, int nt,
                       CouplingJet* patella_rows, Vector6<CouplingJet>* tendon) {
  const PoseTpl<CouplingJet> pose = PoseWithCoordinateDerivatives<kCouplingJetSize>(Eigen::Map<const Vector6d>(y));
  CouplingJet x[kPatellaUnknowns];
  for (int i = 0; i < kPatellaUnknowns; ++i) x[i] = CouplingJet(y[nt + i], 6 + i);
  return PatellaCouplingRows(patella, pressing, QuadricepsMagnitude(patella.quadriceps, t), pose, x, patella_rows,
                             tendon);
}

}  // namespace

Model MonolithicSystem::WithoutPatella(const Model& model) {
  if (!model.patella) {
    Throw<InputError>("MonolithicSystem", "the model has no patella: the monolithic DAE couples the tibia to the "
                      "patella (docs/model.md §12)");
  }
  Model tibia = model;
  tibia.patella.reset();
  return tibia;
}

MonolithicSystem::MonolithicSystem(const Model& model, ConstraintLevel level, bool ggl)
    : model_(&model),
      tibia_model_(WithoutPatella(model)),
      tibia_(tibia_model_, ContactForm::kChapter, level, ggl),
      data_(tibia_model_),
      data_jet_(tibia_model_) {}

void MonolithicSystem::SetPhase(const std::vector<int>& active, const std::vector<ContactGuess>& contact,
                                const std::vector<signed char>& ligament_branch) {
  tibia_.SetPhase(active, contact, ligament_branch);
  const int n = size();
  yj_.assign(n, JetD(0.0));
  ypj_.assign(n, JetD(0.0));
  Fj_.assign(n, JetD(0.0));
  tibia_jacobian_.assign(static_cast<size_t>(tibia_.size()) * tibia_.size(), 0.0);
}

std::string MonolithicSystem::UnknownName(int i) const {
  return i < tibia_.size() ? tibia_.UnknownName(i) : std::string(PatellaUnknownName(i - tibia_.size()));
}

void MonolithicSystem::InitialValues(const MechanicalState& state, double* y, double* yp) {
  PatellaGuess* guess = &guess_;
  const int nt = tibia_.size();
  tibia_.InitialValues(state, y, yp);
  const Patella& patella = *model_->patella;
  const Vector3d tuberosity_F = TuberosityInF(patella, PoseFromCoordinates(state.q));
  SolvePatella(patella, tuberosity_F, "MonolithicSystem::InitialValues", guess);
  // The phase's facets: those of SolvePatella's complementarity at the start (the ODE forms'
  // choice in their right-hand side; both unless patella.facet_liftoff). At a lift-off's root
  // λ_i is zero to round-off and the complementarity may keep the facet: the phase's events
  // (solver/events.cpp) treat it as separated from λ_i ≤ kPatellarRecontactRatio / 2, and so
  // does the DAE, whose facets stay fixed over the phase (the ODE forms' right-hand side
  // separates it at its first λ_i < 0).
  if (patella.facet_liftoff) {
    for (int i = 0; i < 2; ++i) {
      if (!guess->pressing[i] || guess->x[kPatellaFacetRatio + i] > 0.5 * kPatellarRecontactRatio) continue;
      PatellaFacets separated = guess->pressing;
      separated[i] = false;
      std::array<double, kPatellaUnknowns> x = guess->x;
      if (SolvePatellaWithFacets(patella, tuberosity_F, separated, &x)) {
        guess->x = x;
        guess->pressing = separated;
      }
    }
  }
  pressing_ = guess->pressing;
  for (int i = 0; i < kPatellaUnknowns; ++i) {
    y[nt + i] = guess->x[i];
    yp[nt + i] = 0.0;
  }
  // ẋ = −(∂r/∂x)⁻¹ ∂r/∂q q̇ (r does not depend on t: the quadriceps magnitude divides out).
  CouplingJet r[kPatellaUnknowns];
  Vector6<CouplingJet> tendon;
  if (!LinearizeCoupling(patella, pressing_, state.t, y, nt, r, &tendon)) return;
  PatellaJacobian A;
  Eigen::Matrix<double, kPatellaUnknowns, 1> b;
  for (int i = 0; i < kPatellaUnknowns; ++i) {
    b(i) = 0.0;
    for (int j = 0; j < 6; ++j) b(i) -= r[i].v[j] * state.qd(j);
    for (int j = 0; j < kPatellaUnknowns; ++j) A(i, j) = r[i].v[6 + j];
  }
  const Eigen::Matrix<double, kPatellaUnknowns, 1> xd = A.partialPivLu().solve(b);
  for (int i = 0; i < kPatellaUnknowns; ++i) yp[nt + i] = xd(i);
}

bool MonolithicSystem::Jacobian(double t, double cj, const double* y, const double* yp, double* Jdata,
                                bool J_is_zero) const {
  const int nt = tibia_.size(), n = size();
  if (!tibia_.Jacobian(t, cj, y, yp, tibia_jacobian_.data())) return false;
  Eigen::Map<MatrixXd> J(Jdata, n, n);
  if (!J_is_zero) J.setZero();
  J.topLeftCorner(nt, nt) = Eigen::Map<const MatrixXd>(tibia_jacobian_.data(), nt, nt);
  CouplingJet r[kPatellaUnknowns];
  Vector6<CouplingJet> tendon;
  if (!LinearizeCoupling(*model_->patella, pressing_, t, y, nt, r, &tendon)) return false;
  for (int i = 0; i < kPatellaUnknowns; ++i) {
    for (int j = 0; j < 6; ++j) J(nt + i, j) = r[i].v[j];
    for (int j = 0; j < kPatellaUnknowns; ++j) J(nt + i, nt + j) = r[i].v[6 + j];
  }
  for (int i = 0; i < 6; ++i) {
    for (int j = 0; j < 6; ++j) J(6 + i, j) += tendon(i).v[j];
    for (int j = 0; j < kPatellaUnknowns; ++j) J(6 + i, nt + j) = tendon(i).v[6 + j];
  }
  return true;
}

bool MonolithicSystem::JacobianByJets(double t, double cj, const double* y, const double* yp, double* J) const {
  const int n = size();
  std::fill(J, J + static_cast<size_t>(n) * n, 0.0);
  // Columns 0 … n−1 are ∂/∂y, n … 2n−1 ∂/∂ẏ; kMaxJetSize of them per pass.
  for (int first = 0; first < 2 * n; first += kMaxJetSize) {
    const int last = std::min(first + kMaxJetSize, 2 * n);
    for (int i = 0; i < n; ++i) {
      yj_[i] = JetD(y[i]);
      ypj_[i] = JetD(yp[i]);
    }
    for (int col = first; col < last; ++col) {
      if (col < n) yj_[col].v[col - first] = 1.0;
      else ypj_[col - n].v[col - first] = 1.0;
    }
    if (!Residual(t, yj_.data(), ypj_.data(), Fj_.data(), &data_jet_)) return false;
    for (int col = first; col < last; ++col) {
      const int unknown = col < n ? col : col - n;
      const double scale = col < n ? 1.0 : cj;
      for (int r = 0; r < n; ++r) J[r + static_cast<size_t>(n) * unknown] += scale * Fj_[r].v[col - first];
    }
  }
  return true;
}

}  // namespace kneedyn
