// The patello-femoral joint (docs/model.md §12; chapter §1.7, Eq. 1.63): the massless
// patella's 17 equations at a tibial pose, their Newton solve, and the patellar tendon force
// they give the tibia.
//
// Unknowns x (PatellaUnknown): the six patello-femoral coordinates (origin of P in F, m:
// medial–lateral shift, anterior–posterior and proximal–distal translation; patellar
// flexion, tilt and rotation, rad, in the JCS of the tibia: R_FP = Rx(−φ) Ry(−τ) Rz(−ρ),
// i.e. RotationFT(φ, π/2 + τ, ρ)), per facet the four regular-chart contact coordinates
// (uf, vf, up, vp), the facet-force/quadriceps ratios λ = N / F_Q and the tendon/quadriceps
// ratio τ_t = F_t / F_Q. Equations r:
//   r[0..4], r[5..9]  contact of the medial and lateral facets (ChapterContactResiduals,
//                     regular chart: Eq. 1.8 and Eq. 1.13 as for the tibia)
//   r[10..12]         Σ forces / F_Q = û_Q + τ_t û_t − Σ λ_i n_F,i = 0      (F components)
//   r[13..15]         Σ moments about the origin of P / F_Q = 0             (m, F components)
//   r[16]             |R_a − R_t| − L_t = 0, the rigid tendon                 (m)
// with û_t = (R_a − R_t)/|R_a − R_t| from the apex R_t to the tuberosity R_a (Eq. 1.63) and
// the contact force −N n_F on the patella (n_F its facet normal towards the femur).
// Dividing by F_Q leaves the pose independent of the quadriceps magnitude: the solution is
// a function of the tuberosity's position in F alone, and F_t = τ_t F_Q(t).
//
// Facet lift-off (docs/model.md §12; Patella::facet_liftoff, else both always press): a facet presses (λ_i ≥ 0) or is separated (gap_i ≥ 0),
// never both (λ_i gap_i = 0). A separated facet keeps the layout: its row r[5i+2], the gap
// e·n of Eq. 1.8, becomes λ_i = 0, and its four chart coordinates still solve the other
// four rows, so they stay the closest pair of points of the two surfaces and e·n is the
// separated facet's gap. SolvePatella chooses which facets press (PatellaFacets): the
// solution is continuous in the tuberosity's position; its derivative jumps where a facet
// lifts off or re-contacts, and the events (solver/events.hpp) stop the integrators there.
#pragma once

#include <array>
#include <string>
#include <type_traits>

#include <Eigen/LU>

#include "solver/contact.hpp"
#include "solver/units.hpp"

namespace kneedyn {

constexpr int kPatellaUnknowns = 17;
enum PatellaUnknown {
  kPatellaShift = 0,      // x of P's origin in F, m
  kPatellaAnterior = 1,   // y, m
  kPatellaProximal = 2,   // z, m
  kPatellaFlexion = 3,    // φ, rad
  kPatellaTilt = 4,       // τ, rad
  kPatellaRotation = 5,   // ρ, rad
  kPatellaChart = 6,      // 4 per facet: (uf, vf, up, vp)
  kPatellaFacetRatio = 14,  // λ_medial, λ_lateral
  kPatellaTendonRatio = 16,
};
const char* PatellaUnknownName(int i);  // "patella_shift", ..., "tendon_ratio"

// Quadriceps force magnitude F_Q(t), N (model.hpp), for t ≥ 0.
double QuadricepsMagnitude(const QuadricepsForce& quadriceps, double t);
// True when F_Q(t) > 0 for every t ≥ 0 (a massless patella has no equilibrium otherwise);
// else false with `why` naming the value that breaks it.
bool QuadricepsPositive(const QuadricepsForce& quadriceps, std::string* why);
QuadricepsShape ParseQuadricepsShape(const std::string& name);  // throws InputError
const char* QuadricepsShapeName(QuadricepsShape shape);        // "constant", "ramp", "half_sine"

// Pose of P in F from the unknowns.
template <typename T>
PoseTpl<T> PatellaPose(const T* x) {
  Vector6<T> q;
  q << x[kPatellaShift], x[kPatellaAnterior], x[kPatellaProximal], x[kPatellaFlexion],
      x[kPatellaTilt] + T(0.5 * kPi), x[kPatellaRotation];
  return PoseFromCoordinates(q);
}

// Which facets press on the femur (medial = [0], lateral = [1]); a massless patella needs
// one at least (with none, the quadriceps and the tendon alone cannot balance).
using PatellaFacets = std::array<bool, 2>;
constexpr PatellaFacets kBothFacetsPress = {{true, true}};

// The 17 residuals at the tuberosity position R_a (F, m), both facets pressing. False when
// a contact coordinate leaves its surface's chart.
template <typename T>
bool PatellaResiduals(const Patella& patella, const Vector3<T>& tuberosity_F, const T* x, T* r);

// The same with the facets `pressing`: a separated facet's row r[5i+2] is λ_i (= 0 at a
// solution) instead of its gap; the gap is then *gap_F (m, optional: both facets' e·n).
template <typename T>
bool PatellaResiduals(const Patella& patella, const Vector3<T>& tuberosity_F, const T* x, T* r,
                      const PatellaFacets& pressing, T* gap = nullptr) {
  const PoseTpl<T> pose = PatellaPose(x);
  ContactGeometryTpl<T> geometry[2];
  for (int i = 0; i < 2; ++i) {
    if (!ChapterContactResiduals(patella.facet[i], pose, x + kPatellaChart + 4 * i, r + 5 * i, &geometry[i],
                                 ContactChart::kRegular)) {
      return false;
    }
    if (gap != nullptr) gap[i] = geometry[i].gap;
    if (!pressing[i]) r[5 * i + 2] = x[kPatellaFacetRatio + i];
  }
  const Vector3<T> apex_F = pose.PointInF(patella.apex_P.template cast<T>());
  const Vector3<T> base_F = pose.PointInF(patella.base_P.template cast<T>());
  const Vector3<T> span_F = tuberosity_F - apex_F;
  const T length = span_F.norm();
  const Vector3<T> tendon_F = x[kPatellaTendonRatio] * span_F / length;
  const Vector3<T> quadriceps_F = patella.quadriceps.direction_F.template cast<T>();
  Vector3<T> force = quadriceps_F + tendon_F;
  Vector3<T> moment = (base_F - pose.p_FoTo_F).cross(quadriceps_F) + (apex_F - pose.p_FoTo_F).cross(tendon_F);
  for (int i = 0; i < 2; ++i) {
    const Vector3<T> contact_F = x[kPatellaFacetRatio + i] * (pose.R_FT * geometry[i].normal_T);
    force -= contact_F;
    moment -= (pose.R_FT * geometry[i].point_T).cross(contact_F);
  }
  for (int k = 0; k < 3; ++k) {
    r[10 + k] = force(k);
    r[13 + k] = moment(k);
  }
  r[16] = length - T(patella.tendon_length);
  return true;
}

template <typename T>
bool PatellaResiduals(const Patella& patella, const Vector3<T>& tuberosity_F, const T* x, T* r) {
  return PatellaResiduals(patella, tuberosity_F, x, r, kBothFacetsPress);
}

// Warm start of the solve: the last solution, the tuberosity position it solves at and the
// facets that press there.
struct PatellaGuess {
  std::array<double, kPatellaUnknowns> x{};
  Vector3d tuberosity_F = Vector3d::Zero();
  PatellaFacets pressing = kBothFacetsPress;
  bool valid = false;  // false: start from the model's start_unknowns
};

// Newton on the 17 equations at R_a = tuberosity_F (m), from *guess, to round-off
// (Jacobian by ceres::Jet). When Newton from the guess fails, continuation: R_a moved from
// the guess's to the target in 2, 4, ..., 256 equal steps. The facets pressing are first
// the guess's; a pressing facet that would pull (λ_i < 0) is separated, a separated one
// whose gap has closed (gap_i < 0) presses again, and the solve repeats (the complementarity
// λ_i ≥ 0, gap_i ≥ 0, λ_i gap_i = 0). On return *guess holds the solution and its facets,
// `jacobian_lu` (optional) the LU of ∂r/∂x there. Throws SolverError naming `caller` and R_a
// when no solution is found or both facets would separate.
using PatellaJacobian = Eigen::Matrix<double, kPatellaUnknowns, kPatellaUnknowns>;
void SolvePatella(const Patella& patella, const Vector3d& tuberosity_F, const char* caller, PatellaGuess* guess,
                  Eigen::PartialPivLU<PatellaJacobian>* jacobian_lu = nullptr);

// Newton on the 17 equations at R_a with the facets `pressing` fixed (no complementarity),
// from *x; true on convergence with *x the solution (a separated facet's λ_i exactly 0).
bool SolvePatellaWithFacets(const Patella& patella, const Vector3d& tuberosity_F, const PatellaFacets& pressing,
                            std::array<double, kPatellaUnknowns>* x);

// Max |r_i| at a solution (m for positions, dimensionless for forces / F_Q).
double PatellaResidualNorm(const Patella& patella, const Vector3d& tuberosity_F,
                           const std::array<double, kPatellaUnknowns>& x,
                           const PatellaFacets& pressing = kBothFacetsPress);

// Gaps e·n of both facets (m) at unknowns x: 0 for a pressing facet at a solution.
std::array<double, 2> PatellaFacetGaps(const Patella& patella, const std::array<double, kPatellaUnknowns>& x);

// The facet's contact function at a solution: λ_i − gap_i / (1 m), i.e. λ_i (−) while it
// presses and −gap_i (m) while it is separated. Continuous through the switch and zero
// there: positive in contact, negative when separated (the events' g, solver/events.hpp).
double PatellarContactFunction(const Patella& patella, const PatellaGuess& solution, int facet);

// ∂gap_i/∂λ_i (m per unit λ_i) along the equilibrium with the other 16 equations held,
// at the solution x (facet i's row read as λ_i = μ, the others as in `x`'s facets): the
// facet's complementarity compliance. At a facet's switch (λ_i = gap_i = 0) the one-facet
// branch continues past a lift-off or re-contact only when it is positive: with the
// two-facet λ_i(R_a) crossing zero, the one-facet gap is −(∂gap_i/∂λ_i) λ_i to first order,
// so a negative compliance means the separated facet penetrates where the pressing one pulls
// (the branch folds back, docs/model.md §12).
double PatellarFacetCompliance(const Patella& patella, const Vector3d& tuberosity_F,
                               const std::array<double, kPatellaUnknowns>& x, int facet);

// A facet's contact function this close to zero (|c_i| ≤ this: λ_i ≤ 1e-6, i.e. 1e-6 F_Q,
// or a gap ≤ 1 µm) marks a switch at a phase start: the events' roots leave it ~1e-12 and
// the re-contact hysteresis 1e-9 (solver/events.hpp).
constexpr double kPatellarSwitchBand = 1.0e-6;

// At a phase start at tibial time t (s), the patella's equilibrium `solution` at R_a: each
// facet at its switch (|c_i| ≤ kPatellarSwitchBand) must have a positive compliance, else
// SolverError naming the facet, t, R_a (mm), λ_i, gap_i (mm) and ∂gap_i/∂λ_i (mm): the
// one-facet branch has folded back and the massless patella has no equilibrium past the
// switch (it would snap). The check runs where a run has to continue past the switch, not in
// the integrators' evaluations while they locate it (docs/model.md §12).
void CheckPatellarFacetSwitch(const Patella& patella, const Vector3d& tuberosity_F, const PatellaGuess& solution,
                              double t, const char* caller);

// Tuberosity R_a in F at the tibial pose (Eq. 1.63).
template <typename T>
Vector3<T> TuberosityInF(const Patella& patella, const PoseTpl<T>& tibia) {
  return tibia.PointInF(patella.tuberosity_T.template cast<T>());
}

// The patellar tendon's force on the tibia at the tuberosity R_a = tuberosity_F (m) from the
// patella's unknowns x and the quadriceps magnitude F_Q (N): F_t (R_t − R_a)/|R_t − R_a|
// (F components, N; the reaction of Eq. 1.63, R_t the apex), with *tension = F_t = τ_t F_Q (N).
// PatellarTendonForce (the solved patella) and the monolithic DAE (x as unknowns) both use it.
template <typename T>
Vector3<T> TendonForceOnTibia_F(const Patella& patella, const Vector3<T>& tuberosity_F, const T* x,
                                double quadriceps, T* tension) {
  const Vector3<T> apex_F = PatellaPose(x).PointInF(patella.apex_P.template cast<T>());
  const Vector3<T> span_F = apex_F - tuberosity_F;
  *tension = x[kPatellaTendonRatio] * quadriceps;
  return *tension * (span_F / span_F.norm());
}

// The moment (N m, T components) of the tendon force force_F (F components, N) about the
// tibia's centre of mass: it acts at the tuberosity (Eq. 1.63; as ComputeAppliedWrench adds it).
template <typename T>
Vector3<T> TendonMomentOnTibia_T(const Patella& patella, const PoseTpl<T>& tibia, const Vector3<T>& force_F) {
  return patella.tuberosity_T.template cast<T>().cross(tibia.R_FT.transpose() * force_F);
}

// The patellar tendon's pull on the tibia at a tibial pose and time: tension F_t (N) and
// its force on the tibia at the tuberosity, F_t (R_t − R_a)/|R_t − R_a| (F components; the
// reaction of Eq. 1.63). For T = ceres::Jet the double solution is lifted by the implicit
// function theorem (as the contact kinematics do): x = x* − J⁻¹ r(x*, R_a(T)), exact first
// derivatives with respect to the tibial pose.
template <typename T>
void PatellarTendonForce(const Patella& patella, double t, const PoseTpl<T>& tibia, PatellaGuess* guess,
                         T* tension, Vector3<T>* force_F) {
  const Vector3<T> tuberosity_F = TuberosityInF(patella, tibia);
  Vector3d tuberosity_d;
  for (int k = 0; k < 3; ++k) tuberosity_d(k) = ScalarPart(tuberosity_F(k));
  const double quadriceps = QuadricepsMagnitude(patella.quadriceps, t);
  if constexpr (std::is_same_v<T, double>) {
    SolvePatella(patella, tuberosity_d, "PatellarTendonForce", guess);
    *force_F = TendonForceOnTibia_F(patella, tuberosity_F, guess->x.data(), quadriceps, tension);
  } else {
    Eigen::PartialPivLU<PatellaJacobian> lu;
    SolvePatella(patella, tuberosity_d, "PatellarTendonForce", guess, &lu);
    T x[kPatellaUnknowns], r[kPatellaUnknowns];
    for (int i = 0; i < kPatellaUnknowns; ++i) x[i] = T(guess->x[i]);
    PatellaResiduals(patella, tuberosity_F, x, r, guess->pressing);
    // Only the derivative parts: r(x*) is zero to round-off.
    Eigen::Matrix<T, kPatellaUnknowns, 1> rhs;
    for (int i = 0; i < kPatellaUnknowns; ++i) rhs(i) = r[i] - T(ScalarPart(r[i]));
    const PatellaJacobian inverse = lu.inverse();
    for (int i = 0; i < kPatellaUnknowns; ++i) {
      T dx = T(0.0);
      for (int j = 0; j < kPatellaUnknowns; ++j) dx -= inverse(i, j) * rhs(j);
      x[i] += dx;
    }
    // F_t (R_t − R_a)/|R_t − R_a| as TendonForceOnTibia_F, rounded as (F_t span)/|span|: the
    // Jacobians of dae and ede are built on this order.
    const PoseTpl<T> pose = PatellaPose(x);
    const Vector3<T> apex_F = pose.PointInF(patella.apex_P.template cast<T>());
    *tension = x[kPatellaTendonRatio] * quadriceps;
    const Vector3<T> span = apex_F - tuberosity_F;
    *force_F = *tension * span / span.norm();
  }
}

// What the staggered scheme carries from one step to the next (chapter §1.7): the apex
// position R_t (F, m) and the tendon tension F_t (N) of the patella's equilibrium at the end
// of the previous step; the tendon then pulls the tibia towards R_t from the tuberosity's
// current position.
struct LaggedTendon {
  Vector3d apex_F = Vector3d::Zero();
  double tension = 0.0;
};
// The equilibrium's apex position and tension at a tibial pose and time t (s).
inline LaggedTendon SolvedTendon(const Patella& patella, double t, const Pose& tibia, PatellaGuess* guess) {
  SolvePatella(patella, TuberosityInF(patella, tibia), "SolvedTendon", guess);
  LaggedTendon out;
  out.apex_F = PatellaPose(guess->x.data()).PointInF(patella.apex_P);
  out.tension = guess->x[kPatellaTendonRatio] * QuadricepsMagnitude(patella.quadriceps, t);
  return out;
}

// The equilibrium followed along a tibial path from from_q to to_q (≤ 1° per step, the
// tibia turning about the knee's centre), from *guess (a solution at from_q; an invalid one
// is the builder's start): the branch a run between the two poses follows, where a straight
// solve could land on another (e.g. a dislocated one-facet equilibrium). *guess holds the
// solution at to_q. Throws SolverError as SolvePatella.
void SolvePatellaAlongTibialPath(const Patella& patella, const Vector6d& from_q, const Vector6d& to_q,
                                 const char* caller, PatellaGuess* guess);

// The start of the solve for a scene (the model builder): from a geometric guess at the
// reference tibial pose (zero patellar angles, both facets touching, the tendon at its
// length), Newton there, then continuation to `initial_q` (angles linear, the tibia turning
// about the knee's centre).
// Fills patella->start_unknowns and start_q. Throws InputError when no equilibrium is found.
void SolvePatellaStart(const Vector6d& reference_q, const Vector6d& initial_q, Patella* patella);

}  // namespace kneedyn
