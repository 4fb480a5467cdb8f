#include "solver/patella.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "solver/error.hpp"
#include "solver/height_field.hpp"
#include "solver/units.hpp"

namespace kneedyn {
namespace {

using PatellaJet = ceres::Jet<double, kPatellaUnknowns>;
constexpr int kMaxNewtonIterations = 30;
// Newton stops one step after max |Δx| ≤ this (m, rad, chart units, force ratios): the
// convergence is quadratic, so that last step reaches round-off.
constexpr double kNewtonStepTolerance = 1.0e-10;

// Where the trochlear contact points are, for the refusals below: a patellar residual fails
// only when a sphere's regular chart does (height_field.hpp; the facet planes' chart has no
// edge).
std::string TrochlearChartCoordinates(const std::array<double, kPatellaUnknowns>& x) {
  return StrCat("trochlear chart (u, v) = (", RadToDeg(x[kPatellaChart]), ", ", RadToDeg(x[kPatellaChart + 1]),
                ") deg medial, (", RadToDeg(x[kPatellaChart + 4]), ", ", RadToDeg(x[kPatellaChart + 5]),
                ") deg lateral; the chart ends at |u| = ", RadToDeg(kUnitSphereChartMaxLatitude), ", |v| = ",
                RadToDeg(kUnitSphereChartMaxLongitude), " deg");
}

// The trochlear chart coordinate nearest its edge, as "medial"/"lateral" and its distance to
// the edge (rad), for the diagnosis of a failed continuation.
std::pair<const char*, double> TrochlearChartMargin(const std::array<double, kPatellaUnknowns>& x) {
  std::pair<const char*, double> nearest{"", std::numeric_limits<double>::infinity()};
  for (int sphere = 0; sphere < 2; ++sphere) {
    const int u = kPatellaChart + 4 * sphere;
    const double margin = std::min(kUnitSphereChartMaxLatitude - std::abs(x[u]),
                                   kUnitSphereChartMaxLongitude - std::abs(x[u + 1]));
    if (margin < nearest.second) nearest = {sphere == 0 ? "medial" : "lateral", margin};
  }
  return nearest;
}

// A contact point this close to its chart's edge (rad) when the continuation fails names the
// edge as the reason: there the model's geometry ends, whatever the equilibrium does past it
// (on hard/patella_quadriceps_2000N an independent solve followed it 50 % further, its
// Jacobian regular: no fold).
constexpr double kChartEdgeMargin = DegToRad(2.0);

// r(x) and ∂r/∂x at x; false outside a chart.
bool Linearize(const Patella& patella, const Vector3d& tuberosity_F, const std::array<double, kPatellaUnknowns>& x,
               const PatellaFacets& pressing, Eigen::Matrix<double, kPatellaUnknowns, 1>* r, PatellaJacobian* J) {
  PatellaJet xj[kPatellaUnknowns], rj[kPatellaUnknowns];
  for (int i = 0; i < kPatellaUnknowns; ++i) xj[i] = PatellaJet(x[i], i);
  if (!PatellaResiduals(patella, Vector3<PatellaJet>(tuberosity_F.cast<PatellaJet>()), xj, rj, pressing)) return false;
  for (int i = 0; i < kPatellaUnknowns; ++i) {
    (*r)(i) = rj[i].a;
    J->row(i) = rj[i].v.transpose();
    if (!std::isfinite(rj[i].a)) return false;
  }
  return true;
}

// Newton from *x at R_a; true on convergence (then *x is the solution).
bool Newton(const Patella& patella, const Vector3d& tuberosity_F, const PatellaFacets& pressing,
            std::array<double, kPatellaUnknowns>* x, Eigen::PartialPivLU<PatellaJacobian>* lu_out) {
  Eigen::Matrix<double, kPatellaUnknowns, 1> r;
  PatellaJacobian J;
  bool last = false;
  for (int iteration = 0; iteration < kMaxNewtonIterations; ++iteration) {
    if (!Linearize(patella, tuberosity_F, *x, pressing, &r, &J)) return false;
    Eigen::PartialPivLU<PatellaJacobian> lu(J);
    const Eigen::Matrix<double, kPatellaUnknowns, 1> dx = -lu.solve(r);
    if (!dx.allFinite()) return false;
    for (int i = 0; i < kPatellaUnknowns; ++i) (*x)[i] += dx(i);
    if (last) {
      // A separated facet's λ_i is exactly zero (its row is linear in it).
      for (int i = 0; i < 2; ++i) {
        if (!pressing[i]) (*x)[kPatellaFacetRatio + i] = 0.0;
      }
      if (lu_out != nullptr) *lu_out = lu;
      return true;
    }
    if (dx.cwiseAbs().maxCoeff() <= kNewtonStepTolerance) last = true;
  }
  return false;
}

}  // namespace

const char* PatellaUnknownName(int i) {
  static const char* const kNames[kPatellaUnknowns] = {
      "patella_shift", "patella_anterior", "patella_proximal", "patella_flexion", "patella_tilt",
      "patella_rotation", "medial_uf", "medial_vf", "medial_up", "medial_vp", "lateral_uf", "lateral_vf",
      "lateral_up", "lateral_vp", "medial_facet_ratio", "lateral_facet_ratio", "tendon_ratio"};
  return i >= 0 && i < kPatellaUnknowns ? kNames[i] : "?";
}

double QuadricepsMagnitude(const QuadricepsForce& q, double t) {
  const double s = std::max(t, 0.0) / q.duration;
  switch (q.shape) {
    case QuadricepsShape::kConstant:
      return q.magnitude;
    case QuadricepsShape::kRamp:
      return q.baseline + (q.magnitude - q.baseline) * std::min(s, 1.0);
    case QuadricepsShape::kHalfSine:
      return s <= 1.0 ? q.baseline + q.magnitude * std::sin(kPi * s) : q.baseline;
  }
  return 0.0;
}

bool QuadricepsPositive(const QuadricepsForce& q, std::string* why) {
  // Extremes over t ≥ 0: the magnitude (constant); both ends (ramp: linear, then constant);
  // the base and the peak base + magnitude (half-sine, sin ∈ [0, 1]).
  const char* shape = QuadricepsShapeName(q.shape);
  auto fail = [&](const char* field, double value, const std::string& rule) {
    if (why) *why = StrCat("patella.quadriceps.", field, " = ", value, " N with shape ", shape, ": ", rule);
    return false;
  };
  switch (q.shape) {
    case QuadricepsShape::kConstant:
      if (!(q.magnitude > 0.0)) return fail("magnitude_N", q.magnitude, "the quadriceps force must be > 0");
      return true;
    case QuadricepsShape::kRamp:
      if (!(q.baseline > 0.0)) {
        return fail("baseline_N", q.baseline, "the ramp starts there at t = 0; the quadriceps force must be > 0 over the run");
      }
      if (!(q.magnitude > 0.0)) {
        return fail("magnitude_N", q.magnitude, "the ramp ends there; the quadriceps force must be > 0 over the run");
      }
      return true;
    case QuadricepsShape::kHalfSine:
      if (!(q.baseline > 0.0)) {
        return fail("baseline_N", q.baseline, "the half-sine starts and ends there; the quadriceps force must be > 0 over the run");
      }
      if (!(q.baseline + q.magnitude > 0.0)) {
        return fail("magnitude_N", q.magnitude, StrCat("baseline + magnitude = ", q.baseline + q.magnitude,
                                                       " N at the peak; the quadriceps force must be > 0 over the run"));
      }
      return true;
  }
  return false;
}

QuadricepsShape ParseQuadricepsShape(const std::string& name) {
  if (name == "constant") return QuadricepsShape::kConstant;
  if (name == "ramp") return QuadricepsShape::kRamp;
  if (name == "half_sine") return QuadricepsShape::kHalfSine;
  Throw<InputError>("ParseQuadricepsShape", "unknown quadriceps shape '", name, "'; expected one of: constant, ramp, half_sine");
}

const char* QuadricepsShapeName(QuadricepsShape shape) {
  switch (shape) {
    case QuadricepsShape::kConstant: return "constant";
    case QuadricepsShape::kRamp: return "ramp";
    case QuadricepsShape::kHalfSine: return "half_sine";
  }
  return "?";
}

namespace {

// Newton at R_a from *x with the facets *pressing, then the complementarity (patella.hpp): a
// pressing facet that pulls is separated, a separated one that penetrates presses, and
// Newton again. The switched solution is taken when it holds (the separated facet does not
// penetrate, the pressing one does not pull); otherwise the first stands: past a fold of
// the one-facet branch there is no one-facet equilibrium (the patella would snap, which a
// massless model cannot follow). That answer (a facet pressing with λ_i < 0) is what the
// integrators see while they locate the switch's event; a run never goes on with it: the
// phase that starts at the switch stops with the fold's SolverError (CheckPatellarFacetSwitch,
// docs/model.md §12). True with *x, *pressing the solution.
bool SolveComplementarity(const Patella& patella, const Vector3d& tuberosity_F, std::array<double, kPatellaUnknowns>* x,
                          PatellaFacets* pressing, Eigen::PartialPivLU<PatellaJacobian>* jacobian_lu,
                          const char** failure) {
  const std::array<double, kPatellaUnknowns> start = *x;
  if (!Newton(patella, tuberosity_F, *pressing, x, jacobian_lu)) {
    *failure = "Newton from the last solution and 256-step continuation both failed";
    return false;
  }
  auto switched = [&](const std::array<double, kPatellaUnknowns>& y, const PatellaFacets& mode) {
    const std::array<double, 2> gap = PatellaFacetGaps(patella, y);
    PatellaFacets next = mode;
    for (int i = 0; i < 2; ++i) {
      if (mode[i] && y[kPatellaFacetRatio + i] < 0.0) next[i] = false;  // it would pull: lift-off
      if (!mode[i] && gap[i] < 0.0) next[i] = true;                    // it penetrates: re-contact
    }
    return next;
  };
  if (!patella.facet_liftoff) return true;  // both facets press, λ_i of either sign
  const PatellaFacets next = switched(*x, *pressing);
  if (next == *pressing) return true;
  if (!next[0] && !next[1]) {
    *failure = "both patellar facets would separate (λ < 0 on each): a massless patella has no equilibrium "
               "without a contact";
    return false;
  }
  std::array<double, kPatellaUnknowns> y = start;
  if (Newton(patella, tuberosity_F, next, &y, nullptr) && switched(y, next) == next) {
    *x = y;
    *pressing = next;
  }
  // The LU of the solution taken (the switched solve's, or the first's again).
  if (jacobian_lu != nullptr) {
    std::array<double, kPatellaUnknowns> z = *x;
    if (!Newton(patella, tuberosity_F, *pressing, &z, jacobian_lu)) {
      *failure = "Newton from the last solution and 256-step continuation both failed";
      return false;
    }
    *x = z;
  }
  return true;
}

}  // namespace

void SolvePatella(const Patella& patella, const Vector3d& tuberosity_F, const char* caller, PatellaGuess* guess,
                  Eigen::PartialPivLU<PatellaJacobian>* jacobian_lu) {
  if (!guess->valid) {
    guess->x = patella.start_unknowns;
    guess->tuberosity_F = PoseFromCoordinates(patella.start_q).PointInF(patella.tuberosity_T);
    // The builder's solution: a separated facet carries exactly λ_i = 0 there.
    for (int i = 0; i < 2; ++i) guess->pressing[i] = patella.start_unknowns[kPatellaFacetRatio + i] != 0.0;
    guess->valid = true;
  }
  const char* failure = "";
  std::array<double, kPatellaUnknowns> x = guess->x;
  if (!patella.facet_liftoff) guess->pressing = kBothFacetsPress;
  PatellaFacets pressing = guess->pressing;
  bool ok = SolveComplementarity(patella, tuberosity_F, &x, &pressing, jacobian_lu, &failure);
  // Continuation: R_a moved from the guess's to the target in 2, 4, ..., 256 equal steps, the
  // facets chosen again at each.
  std::array<double, kPatellaUnknowns> last_solved = guess->x;  // the finest continuation's last solution
  for (int steps = 2; !ok && steps <= 256; steps *= 2) {
    x = guess->x;
    pressing = guess->pressing;
    ok = true;
    for (int k = 1; k <= steps && ok; ++k) {
      const double s = static_cast<double>(k) / steps;
      const Vector3d target = (1.0 - s) * guess->tuberosity_F + s * tuberosity_F;
      last_solved = x;
      ok = SolveComplementarity(patella, target, &x, &pressing, k == steps ? jacobian_lu : nullptr, &failure);
    }
  }
  if (ok) {
    guess->x = x;
    guess->tuberosity_F = tuberosity_F;
    guess->pressing = pressing;
    return;
  }
  const auto [sphere, margin] = TrochlearChartMargin(last_solved);
  const std::string why =
      margin < kChartEdgeMargin
          ? StrCat("the ", sphere, " trochlear contact point reached the edge of its sphere's chart (",
                   TrochlearChartCoordinates(last_solved), "): the model's trochlear geometry ends there; ", failure)
          : StrCat(failure, " (", TrochlearChartCoordinates(last_solved), ")");
  Throw<SolverError>(caller, "no patellar equilibrium found at the tuberosity position (", MToMm(tuberosity_F.x()), ", ",
                     MToMm(tuberosity_F.y()), ", ", MToMm(tuberosity_F.z()), ") mm in F (from the last solution at (",
                     MToMm(guess->tuberosity_F.x()), ", ", MToMm(guess->tuberosity_F.y()), ", ",
                     MToMm(guess->tuberosity_F.z()), ") mm: ", why, "; docs/model.md §12)");
}

bool SolvePatellaWithFacets(const Patella& patella, const Vector3d& tuberosity_F, const PatellaFacets& pressing,
                            std::array<double, kPatellaUnknowns>* x) {
  return Newton(patella, tuberosity_F, pressing, x, nullptr);
}

double PatellaResidualNorm(const Patella& patella, const Vector3d& tuberosity_F,
                           const std::array<double, kPatellaUnknowns>& x, const PatellaFacets& pressing) {
  double r[kPatellaUnknowns];
  if (!PatellaResiduals(patella, tuberosity_F, x.data(), r, pressing)) return std::numeric_limits<double>::infinity();
  double norm = 0.0;
  for (double v : r) norm = std::max(norm, std::abs(v));
  return norm;
}

std::array<double, 2> PatellaFacetGaps(const Patella& patella, const std::array<double, kPatellaUnknowns>& x) {
  // The gap rows do not depend on the tuberosity or on which facets press.
  double r[kPatellaUnknowns];
  std::array<double, 2> gap{{0.0, 0.0}};
  if (!PatellaResiduals(patella, Vector3d(Vector3d::Zero()), x.data(), r, kBothFacetsPress, gap.data())) {
    Throw<SolverError>("PatellaFacetGaps", "a patellar contact coordinate left its chart: ", TrochlearChartCoordinates(x),
                       " (docs/model.md §12)");
  }
  return gap;
}

double PatellarContactFunction(const Patella& patella, const PatellaGuess& solution, int facet) {
  const double gap = PatellaFacetGaps(patella, solution.x)[facet];
  return solution.pressing[facet] ? solution.x[kPatellaFacetRatio + facet] : -gap;
}

double PatellarFacetCompliance(const Patella& patella, const Vector3d& tuberosity_F,
                               const std::array<double, kPatellaUnknowns>& x, int facet) {
  PatellaFacets separated = kBothFacetsPress;
  separated[facet] = false;
  Eigen::Matrix<double, kPatellaUnknowns, 1> r;
  PatellaJacobian J;
  PatellaJet xj[kPatellaUnknowns], rj[kPatellaUnknowns], gap[2];
  for (int i = 0; i < kPatellaUnknowns; ++i) xj[i] = PatellaJet(x[i], i);
  if (!Linearize(patella, tuberosity_F, x, separated, &r, &J) ||
      !PatellaResiduals(patella, Vector3<PatellaJet>(tuberosity_F.cast<PatellaJet>()), xj, rj, separated, gap)) {
    Throw<SolverError>("PatellarFacetCompliance", "a patellar contact coordinate left its chart: ",
                       TrochlearChartCoordinates(x), " (docs/model.md §12)");
  }
  // J dx = e_k dμ: the separated facet's row λ_i = μ moved, the other 16 held.
  Eigen::Matrix<double, kPatellaUnknowns, 1> e = Eigen::Matrix<double, kPatellaUnknowns, 1>::Zero();
  e(5 * facet + 2) = 1.0;
  const Eigen::Matrix<double, kPatellaUnknowns, 1> dx = J.fullPivLu().solve(e);
  return gap[facet].v.dot(dx);
}

void CheckPatellarFacetSwitch(const Patella& patella, const Vector3d& tuberosity_F, const PatellaGuess& solution,
                              double t, const char* caller) {
  const std::array<double, 2> gap = PatellaFacetGaps(patella, solution.x);
  for (int i = 0; i < 2; ++i) {
    if (std::abs(PatellarContactFunction(patella, solution, i)) > kPatellarSwitchBand) continue;
    const double compliance = PatellarFacetCompliance(patella, tuberosity_F, solution.x, i);
    if (compliance > 0.0) continue;
    Throw<SolverError>(caller, "the patella's ", CompartmentName(static_cast<Compartment>(i)),
                       " facet switches at t = ", t, " s (lambda = ", solution.x[kPatellaFacetRatio + i], ", gap ",
                       MToMm(gap[i]), " mm, tuberosity at (", MToMm(tuberosity_F.x()), ", ", MToMm(tuberosity_F.y()),
                       ", ", MToMm(tuberosity_F.z()), ") mm in F), but d gap/d lambda = ", MToMm(compliance),
                       " mm per unit lambda (lambda = N / F_Q) <= 0 along the equilibrium: past the switch the facet "
                       "would pull while pressing (lambda < 0) and penetrate the trochlea while separated (gap = -(d gap/d lambda) x "
                       "lambda < 0). "
                       "The one-facet branch has folded back: the massless patella has no equilibrium here "
                       "(it would snap), docs/model.md §12");
  }
}

void SolvePatellaAlongTibialPath(const Patella& patella, const Vector6d& from_q, const Vector6d& to_q,
                                 const char* caller, PatellaGuess* guess) {
  // 1° or less per step: the angles interpolated linearly and the tibial point that sits at
  // F's origin at from_q (the knee's centre) moved on the straight line between its
  // positions, so that the tibia turns about the knee, as it does, and not about its centre
  // of mass.
  const Pose from = PoseFromCoordinates(from_q), to = PoseFromCoordinates(to_q);
  const Vector3d knee_T = from.PointInT(Vector3d::Zero());
  const Vector3d knee_start_F = Vector3d::Zero(), knee_end_F = to.PointInF(knee_T);
  const double angle = (to_q - from_q).tail<3>().cwiseAbs().maxCoeff();
  const int steps = std::max(1, static_cast<int>(std::ceil(angle / DegToRad(1.0))));
  for (int k = 1; k <= steps; ++k) {
    const double s = static_cast<double>(k) / steps;
    Vector6d q = from_q + (to_q - from_q) * s;
    const Pose rotated = PoseFromCoordinates(q);
    q.head<3>() = (1.0 - s) * knee_start_F + s * knee_end_F - rotated.R_FT * knee_T;
    SolvePatella(patella, PoseFromCoordinates(q).PointInF(patella.tuberosity_T), caller, guess);
  }
}

void SolvePatellaStart(const Vector6d& reference_q, const Vector6d& initial_q, Patella* patella) {
  // Geometric guess at the reference pose: zero angles; the origin o such that each facet
  // plane n_i · (p − o) = d_i touches its sphere, n_i · (C_i − o) − d_i = r_i (two linear
  // equations in o, least-norm in their span); then o moved along the remaining direction
  // until the tendon has its length, the apex proximal of the tuberosity.
  const Vector3d tuberosity_F = PoseFromCoordinates(reference_q).PointInF(patella->tuberosity_T);
  Eigen::Matrix<double, 2, 3> A;
  Eigen::Vector2d b;
  Vector3d centre[2];
  double radius[2];
  Vector3d normal[2];
  double offset[2];
  for (int i = 0; i < 2; ++i) {
    if (!patella->facet[i].femoral_surface->SphereForm(&centre[i], &radius[i]) ||
        !patella->facet[i].tibial_surface->PlaneForm(&normal[i], &offset[i])) {
      Throw<InputError>("SolvePatellaStart", "patellar facet ", i, ": the start guess needs a trochlear sphere and a patellar plane");
    }
    // The patella lies anterior to the trochlea: a facet facing the femur faces posteriorly
    // (−y in P, which is parallel to F here). A reversed normal put the patella inside the
    // femur (behind the trochlear centres) with positive facet forces, or asked for a longer tendon.
    if (!(normal[i].y() < 0.0)) {
      Throw<InputError>("SolvePatellaStart", "patella.facet_", i == 0 ? "medial" : "lateral", ".normal_P = (",
                        normal[i].x(), ", ", normal[i].y(), ", ", normal[i].z(),
                        "): must point from the patella towards the femur, i.e. posteriorly (y < 0; docs/model.md §12)");
    }
    A.row(i) = normal[i].transpose();
    b(i) = normal[i].dot(centre[i]) - offset[i] - radius[i];
  }
  Vector3d origin = A.completeOrthogonalDecomposition().solve(b);
  Vector3d free_direction = normal[0].cross(normal[1]);
  if (free_direction.norm() < 1e-9) {
    Throw<InputError>("SolvePatellaStart", "the two patellar facets' normals (", normal[0].transpose(), ") and (",
                      normal[1].transpose(), ") are parallel (|n_medial x n_lateral| = ", free_direction.norm(),
                      "): the facets must be inclined to each other for the patella's start to be defined");
  }
  free_direction.normalize();
  if (free_direction.z() < 0.0) free_direction = -free_direction;
  // |o + s e + apex − R_a| = L, largest root s.
  const Vector3d w = origin + patella->apex_P - tuberosity_F;
  const double half_b = w.dot(free_direction), c = w.squaredNorm() - patella->tendon_length * patella->tendon_length;
  const double disc = half_b * half_b - c;
  if (!(disc >= 0.0)) {
    // The apex's two-facet positions form a line; its distance from the tuberosity at its closest.
    const double closest = std::sqrt(std::max(0.0, w.squaredNorm() - half_b * half_b));
    Throw<InputError>("SolvePatellaStart", "the tendon (patella.tendon_length_mm = ", MToMm(patella->tendon_length),
                      " mm) cannot reach the tuberosity (patella.tuberosity_T_mm) with both facets in contact: with each "
                      "facet plane (patella.facet_medial, facet_lateral) on its trochlear sphere (patella.trochlea_medial, "
                      "trochlea_lateral), the apex (patella.apex_P_mm) passes ", MToMm(closest),
                      " mm from the tuberosity at its closest, at the reference pose; the tendon must be at least that long "
                      "(docs/model.md §12)");
  }
  origin += (-half_b + std::sqrt(disc)) * free_direction;
  std::array<double, kPatellaUnknowns> x{};
  for (int k = 0; k < 3; ++k) x[k] = origin(k);
  for (int i = 0; i < 2; ++i) {
    const Vector3d on_sphere = centre[i] - radius[i] * normal[i];
    patella->facet[i].femoral_surface->ChartCoordinates(on_sphere, &x[kPatellaChart + 4 * i]);
    patella->facet[i].tibial_surface->ChartCoordinates(on_sphere - origin, &x[kPatellaChart + 4 * i + 2]);
  }
  // Force ratios: least squares of the force balance with the guessed pose.
  const Vector3d apex_F = origin + patella->apex_P;
  Eigen::Matrix3d M;
  M.col(0) = -normal[0];
  M.col(1) = -normal[1];
  M.col(2) = (tuberosity_F - apex_F).normalized();
  const Vector3d ratios = M.completeOrthogonalDecomposition().solve(Vector3d(-patella->quadriceps.direction_F));
  x[kPatellaFacetRatio] = ratios(0);
  x[kPatellaFacetRatio + 1] = ratios(1);
  x[kPatellaTendonRatio] = ratios(2);
  patella->start_q = reference_q;
  patella->start_unknowns = x;
  PatellaGuess guess;
  guess.x = x;
  guess.tuberosity_F = tuberosity_F;
  guess.valid = true;
  try {
    SolvePatella(*patella, tuberosity_F, "SolvePatellaStart", &guess);
    SolvePatellaAlongTibialPath(*patella, reference_q, initial_q, "SolvePatellaStart", &guess);
  } catch (const SolverError& e) {
    // Why, when the start guess already shows it: its force balance needs a pulling facet or tendon.
    std::string why;
    if (ratios.minCoeff() < 0.0) {
      const Vector3d& d = patella->quadriceps.direction_F;
      why = StrCat("; at the start guess (reference pose, both facets on their spheres) the force balance with the "
                   "quadriceps along patella.quadriceps.direction_F (as a unit vector [", d.x(), ", ", d.y(), ", ", d.z(),
                   "]) needs force ratios lambda_medial = ", ratios(0), ", lambda_lateral = ", ratios(1), ", tendon = ",
                   ratios(2), ": a negative one would pull (the quadriceps line against the facet normals "
                   "patella.facet_*.normal_P and the tendon's line from patella.apex_P_mm to patella.tuberosity_T_mm)");
    }
    // The tendon's length places the start guess (above); a long one leaves Newton nothing to
    // find, and the refusal named no key (found by a probe with 400 mm).
    Throw<InputError>("SolvePatellaStart", "no patellar equilibrium at the scene's start with patella.tendon_length_mm = ",
                      MToMm(patella->tendon_length), " mm: ", e.what(), why);
  }
  patella->start_q = initial_q;
  patella->start_unknowns = guess.x;
}

}  // namespace kneedyn
