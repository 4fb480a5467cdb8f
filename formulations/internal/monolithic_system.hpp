// The monolithic DAE of the knee with its patella (chapter §1.7; docs/model.md §12, "The
// monolithic DAE"): the tibia's index-2 DAE of `dae` / `dae-ggl` (DaeSystem,
// formulations/internal/dae_system.hpp) plus the massless patella's 17 unknowns as algebraic
// variables of the same system, for the formulations `monolithic` and `monolithic-ggl`
// (formulations/monolithic.cpp).
//
// Unknowns y (n_t = DaeSystem's size: 22 plain, 24 GGL with both tibial contacts):
//   y[0, n_t)         the tibia's unknowns of dae / dae-ggl (q, u, c_i, N_i, μ_i)
//   y[n_t, n_t + 17)  the patella's x (solver/patella.hpp, PatellaUnknown): six
//                     patello-femoral coordinates, 2 × 4 facet chart coordinates, the
//                     facet-force ratios λ = N / F_Q and the tendon ratio τ_t = F_t / F_Q
// Residual rows:
//   F[0, n_t)         DaeSystem's rows for the tibia without the patella, with the tendon
//                     force F_t = τ_t F_Q(t) of Eq. 1.63 added to the Newton–Euler rows
//                     F7–F12 (force in F at the tuberosity, moment about the COM in T),
//                     taken from the unknowns x (not from a Newton solve)
//   F[n_t, n_t + 17)  PatellaResiduals (solver/patella.hpp) at the tuberosity R_a(q)
// The patella rows do not involve ẏ: x is an algebraic variable fixed by q (∂r/∂x is the
// Newton matrix of SolvePatella, regular at an equilibrium), index 1; the tibia's N stay
// index 2 (index 3 at --constraint-level position), as in dae.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "formulations/internal/dae_system.hpp"
#include "solver/patella.hpp"

namespace kneedyn {

// The patella's residual rows and the tendon's pull on the tibia at the tibial pose, time's
// quadriceps magnitude F_Q (N) and patella unknowns x: `patella_rows` (17) the equations of
// solver/patella.hpp at R_a = TuberosityInF(tibia) with the facets `pressing` (a separated
// facet's gap row is λ_i = 0), `tendon_wrench` the generalized force of
// the tendon on the tibia in ν-coordinates (force τ_t F_Q (R_t − R_a)/|R_t − R_a| in F at the
// tuberosity, Eq. 1.63; its moment about the COM in T): solver/patella.hpp's
// TendonForceOnTibia_F and TendonMomentOnTibia_T, as PatellarTendonForce applies it.
// False outside a facet's chart.
template <typename T>
bool PatellaCouplingRows(const Patella& patella, const PatellaFacets& pressing, double quadriceps,
                         const PoseTpl<T>& tibia, const T* x, T* patella_rows, Vector6<T>* tendon_wrench) {
  const Vector3<T> tuberosity_F = TuberosityInF(patella, tibia);
  if (!PatellaResiduals(patella, tuberosity_F, x, patella_rows, pressing)) return false;
  T tension;
  const Vector3<T> force_F = TendonForceOnTibia_F(patella, tuberosity_F, x, quadriceps, &tension);
  tendon_wrench->template head<3>() = force_F;
  tendon_wrench->template tail<3>() = TendonMomentOnTibia_T(patella, tibia, force_F);
  return true;
}

class MonolithicSystem {
 public:
  // `model` has a patella (InputError otherwise) and outlives the system. `ggl`: the tibia in
  // the Gear–Gupta–Leimkuhler form (dae-ggl); `level` applies to the plain form only.
  MonolithicSystem(const Model& model, ConstraintLevel level, bool ggl);
  MonolithicSystem(const MonolithicSystem&) = delete;
  MonolithicSystem& operator=(const MonolithicSystem&) = delete;

  // The interface of DaeSystem (formulations/internal/dae_system.hpp), which the IDA driver
  // (IdaDriver, dae_on_ida.hpp) runs.
  // The patellar facets that press in this phase (InitialValues; both unless the scene's
  // patella.facet_liftoff lets one separate); a separated facet's gap row is λ_i = 0
  // (solver/patella.hpp), the same 17 unknowns.
  const PatellaFacets& facets() const { return pressing_; }
  // The tibia's phase (DaeSystem::SetPhase).
  void SetPhase(const std::vector<int>& active, const std::vector<ContactGuess>& contact,
                const std::vector<signed char>& ligament_branch);

  const DaeSystem& tibia() const { return tibia_; }
  int tibia_size() const { return tibia_.size(); }
  int size() const { return tibia_.size() + kPatellaUnknowns; }
  int PatellaIndex(int i) const { return tibia_.size() + i; }  // i: PatellaUnknown
  int NormalIndex(int c) const { return tibia_.NormalIndex(c); }
  int per_contact() const { return tibia_.per_contact(); }
  bool IsDifferential(int i) const { return i < 12; }          // q, u; all else algebraic
  std::string UnknownName(int i) const;                        // DaeSystem's, then "patella_shift", ...

  // y, ẏ of a consistent state: the tibia's (DaeSystem::InitialValues), x the patella's
  // equilibrium at the state's tibial pose (SolvePatella from the last phase's solution; its
  // complementarity fixes the phase's facets, facets()), ẋ
  // from the time derivative of the patella rows, ∂r/∂x ẋ = −∂r/∂q q̇.
  void InitialValues(const MechanicalState& state, double* y, double* yp);

  // F(t, y, ẏ) for T = double or JetD with the matching workspace (DataTpl over the tibia's
  // model, without the patella). False outside a surface's domain.
  template <typename T>
  bool Residual(double t, const T* y, const T* yp, T* F, DataTpl<T>* data) const;
  bool Residual(double t, const double* y, const double* yp, double* F) const {
    return Residual(t, y, yp, F, &data_);
  }
  // dF/dy + cj dF/dẏ (column-major n × n): the tibia's exact blocks (DaeSystem::Jacobian)
  // plus the coupling blocks as a Jet over (q, x) (6 + 17 slots). No allocation.
  bool Jacobian(double t, double cj, const double* y, const double* yp, double* J, bool J_is_zero = false) const;
  // The same by forward AD of the whole residual (JetD, 24 columns of (y, ẏ) per pass):
  // the reference (tests/monolithic_test.cpp) and --jacobian jet.
  bool JacobianByJets(double t, double cj, const double* y, const double* yp, double* J) const;

 private:
  static Model WithoutPatella(const Model& model);

  const Model* model_;  // with the patella
  Model tibia_model_;   // the same without it: the tendon is added from x, not solved for
  DaeSystem tibia_;
  mutable Data data_;
  mutable DataTpl<JetD> data_jet_;
  mutable std::vector<JetD> yj_, ypj_, Fj_;
  mutable std::vector<double> tibia_jacobian_;  // n_t × n_t
  PatellaGuess guess_;  // the patella's last equilibrium: warm start of the next phase's x
  PatellaFacets pressing_ = kBothFacetsPress;  // the facets that press in this phase
};

template <typename T>
bool MonolithicSystem::Residual(double t, const T* y, const T* yp, T* F, DataTpl<T>* data) const {
  if (!tibia_.Residual(t, y, yp, F, data)) return false;
  const int nt = tibia_.size();
  Vector6<T> q;
  for (int i = 0; i < 6; ++i) q(i) = y[i];
  Vector6<T> tendon;
  const Patella& patella = *model_->patella;
  if (!PatellaCouplingRows(patella, pressing_, QuadricepsMagnitude(patella.quadriceps, t), PoseFromCoordinates(q),
                           y + nt, F + nt, &tendon)) {
    return false;
  }
  // F7–F12 = Q + Σ N_i G_iᵀ − M ν̇ (dae_system.hpp): the tendon belongs to Q.
  for (int i = 0; i < 6; ++i) F[6 + i] += tendon(i);
  return true;
}

// IDA's absolute tolerance of unknown i (IdaDriver, dae_on_ida.hpp; defined in monolithic.cpp):
// the tibia's DaeUnknownAtol, `atol` for the patella's x.
double DaeUnknownAtol(bool ggl, const MonolithicSystem& system, int i, double atol);

// Test hooks (tests/monolithic_test.cpp). The patella unknowns x of a `monolithic` /
// `monolithic-ggl` formulation at the end of its last Advance (the state it wrote back);
// false for another formulation or before the first Advance.
bool MonolithicPatellaUnknownsForTesting(const Formulation& formulation, std::array<double, kPatellaUnknowns>* x);

}  // namespace kneedyn
