#include "formulations/run.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <Eigen/LU>

#include "solver/constrained_dynamics.hpp"
#include "solver/contact_kinematics.hpp"
#include "solver/error.hpp"
#include "solver/units.hpp"

namespace kneedyn {

void ConstraintResiduals(const Model& model, const MechanicalState& state,
                         std::vector<double>* gap, std::vector<double>* gap_rate) {
  const Pose pose = PoseFromCoordinates(state.q);
  const Vector6d nu = GeneralizedVelocity(state.q, state.qd);
  gap->assign(model.contacts.size(), std::nan(""));
  gap_rate->assign(model.contacts.size(), std::nan(""));
  for (size_t i = 0; i < model.contacts.size(); ++i) {
    ContactGeometry g;
    if (!ContactKinematics(model.contacts[i], pose, &g)) continue;
    (*gap)[i] = g.gap;
    (*gap_rate)[i] = ContactConstraintRow(pose, g).dot(nu);
  }
}

namespace {

// Perfectly plastic impact of the contacts in `active` (spec §4): the impulse along the
// normals that zeroes their normal approach velocity, M Δν = Gᵀ P, G (ν + Δν) = 0.
void ApplyPlasticImpact(const Model& model, MechanicalState* state) {
  const Pose pose = PoseFromCoordinates(state->q);
  const int k = static_cast<int>(state->active.size());
  MatrixXd A = MatrixXd::Zero(6 + k, 6 + k);
  VectorXd b = VectorXd::Zero(6 + k);
  A.topLeftCorner<6, 6>() = MassMatrix(model);
  const Vector6d nu = GeneralizedVelocity(state->q, state->qd);
  for (int r = 0; r < k; ++r) {
    const Eigen::Matrix<double, 1, 6> G = ContactConstraintRow(
        pose, RequireContactKinematics(model.contacts[state->active[r]], pose, "ApplyPlasticImpact"));
    A.block<1, 6>(6 + r, 0) = G;
    A.block<6, 1>(0, 6 + r) = -G.transpose();
    b(6 + r) = -G.dot(nu);
  }
  const VectorXd x = A.fullPivLu().solve(b);
  state->qd = CoordinateVelocity(state->q, nu + x.head<6>());
}

// A sample no formulation may report as a result:
// - a non-finite state;
// - an active contact violated by more than kMaxConstraintViolation: velocity-level and
//   fixed-step methods drift, but by far less (≤ 1e-4 mm at the chapter's settings); beyond
//   1 mm the run has diverged (e.g. Euler outside its stability range);
// - a contact point off its femoral surface: the surfaces are height fields over a
//   footprint (for the chapter, the lower half of each sphere). Closed-form formulations
//   would carry a contact past the rim silently; the chapter form cannot. Both stop there:
//   the model is not defined beyond.
constexpr double kMaxConstraintViolation = 1.0e-3;  // m

void CheckSampleIsPhysical(const Model& model, const MechanicalState& s) {
  if (!s.q.allFinite() || !s.qd.allFinite()) {
    Throw<SolverError>("RunScene", "non-finite state at t = ", s.t, " s: the run has diverged");
  }
  const Pose pose = PoseFromCoordinates(s.q);
  for (int i : s.active) {
    const ContactPair& pair = model.contacts[i];
    double x = s.contact[i].coordinates[0], y = s.contact[i].coordinates[1];
    ContactGeometry g;
    if (ContactKinematics(pair, pose, &g)) {
      x = g.point_F.x();
      y = g.point_F.y();
      if (std::abs(g.gap) > kMaxConstraintViolation) {
        Throw<SolverError>("RunScene", "the ", CompartmentName(pair.compartment),
                           " contact constraint is violated by ", MToMm(g.gap), " mm at t = ", s.t,
                           " s (limit ", MToMm(kMaxConstraintViolation),
                           " mm): the run has diverged");
      }
    }
    HeightSample sample;
    if (!pair.femoral_surface->Evaluate(x, y, &sample)) {
      Throw<SolverError>("RunScene", "the ", CompartmentName(pair.compartment),
                         " contact point left the femoral surface (", pair.femoral_surface->Describe(),
                         ") at t = ", s.t, " s, flexion = ", RadToDeg(s.q(kAlpha)),
                         " deg: the model is not defined beyond its rim");
    }
  }
}

// Issue 18: the physical situation beside a solver's failure message: the last state the
// driver holds (time, flexion), the active contacts and their constraint residuals.
std::string FailureSituation(const Model& model, const MechanicalState& s) {
  std::string out = StrCat("; last state t = ", s.t, " s, flexion = ", RadToDeg(s.q(kAlpha)),
                           " deg, active contacts: ");
  if (s.active.empty()) out += "none";
  std::vector<double> gap, rate;
  ConstraintResiduals(model, s, &gap, &rate);
  for (size_t n = 0; n < s.active.size(); ++n) {
    const int i = s.active[n];
    out += StrCat(n ? ", " : "", CompartmentName(model.contacts[i].compartment), " (gap ", MToMm(gap[i]),
                  " mm, gap rate ", MToMm(rate[i]), " mm/s, N = ", s.contact[i].normal_force, " N)");
  }
  return out;
}

}  // namespace

RunResult RunScene(const Scene& scene, const RunSettings& settings) {
  const auto wall_start = std::chrono::steady_clock::now();
  const Model& model = scene.model;
  RunResult result;
  std::unique_ptr<Formulation> formulation =
      CreateFormulation(settings.formulation, scene, settings.options);
  // 0 means the scene's interval; anything else must be usable (issue 18: no silent fallback).
  const double dt = settings.output_interval == 0.0 ? scene.output_interval : settings.output_interval;
  std::string why;
  if (!IsValidOutputInterval(dt, scene.end.time, &why)) {
    Throw<InputError>("RunScene", settings.output_interval == 0.0 ? "scene output.interval_s: " : "--output-interval: ", why);
  }

  ConsistentInitOptions init_options = settings.init;
  init_options.form = formulation->contact_form();
  init_options.chart = settings.options.contact_chart;
  std::vector<int> active;
  for (int i = 0; i < static_cast<int>(model.contacts.size()); ++i) active.push_back(i);
  MechanicalState state = ConsistentInitialize(scene.model, scene.initial, active, init_options, &result.init);
  // Refusals the input causes are raised here, before integration (exit code 2): contact
  // rows that are dependent at the start (e.g. two compartments given the same surfaces).
  SolveConstrainedAcceleration(model, state.t, state.q, state.qd, state.active);

  auto record = [&](const MechanicalState& s, bool is_event) {
    CheckSampleIsPhysical(model, s);
    result.samples.push_back(s);
    result.sample_is_event.push_back(is_event);
    std::vector<double> gap, rate;
    ConstraintResiduals(model, s, &gap, &rate);
    for (int i : s.active) {
      if (std::isfinite(gap[i])) result.max_position_residual = std::max(result.max_position_residual, std::abs(gap[i]));
      if (std::isfinite(rate[i])) result.max_velocity_residual = std::max(result.max_velocity_residual, std::abs(rate[i]));
    }
    if (settings.progress) settings.progress(s.t, s.q(kAlpha));
  };
  record(state, false);

  const double t_end = scene.end.time;
  long next_index = 1;  // next uniform output time = next_index * dt
  bool done = false;
  try {
    while (!done) {
      // Re-contact hysteresis: ten times the drift level (observed gap residuals, and the
      // adaptive methods' position tolerance).
      const double gap_tolerance =
          10.0 * std::max(result.max_position_residual,
                          settings.options.rtol * state.q.head<3>().norm() + settings.options.atol);
      const std::vector<EventSpec> specs = EventsForPhase(scene.model, scene.end, state, gap_tolerance);
      if (model.ligament_law == LigamentLaw::kPublished) {
        state.ligament_branch = LigamentBranchesAt(model, state.q, state.qd);
        CompleteHiddenConstraint(scene.model, &state);  // forces on the locked branches
      }
      formulation->Start(state, specs);
      bool phase_over = false;
      while (!phase_over) {
        const double t_next = std::min(next_index * dt, t_end);
        const AdvanceResult adv = formulation->Advance(t_next, &state);
        if (adv.status == AdvanceStatus::kReachedTime) {
          record(state, false);
          if (t_next >= t_end) {
            result.end_reason = "end_time";
            done = phase_over = true;
          }
          ++next_index;
          continue;
        }
        // A ligament crossing the published law's jump only restarts the formulation.
        const bool only_kinks = std::all_of(adv.events.begin(), adv.events.end(), [&](int k) {
          return specs[k].kind == EventKind::kLigamentKink;
        });
        if (only_kinks) {
          ++result.ligament_kink_crossings;
          phase_over = true;
          break;
        }
        // Events: record them, then switch mode. A uniform output time that coincides
        // with the event is skipped so that times stay strictly increasing.
        if (std::abs(state.t - next_index * dt) < 1e-12) ++next_index;
        record(state, true);
        std::vector<int> new_active = state.active;
        bool impact = false;
        for (int k : adv.events) {
          const EventSpec& e = specs[k];
          result.events.push_back({e.name, state.t, state.q(kAlpha)});
          switch (e.kind) {
            case EventKind::kFlexionEnd:
              result.end_reason = e.name;
              done = true;
              break;
            case EventKind::kLiftoff:
              new_active.erase(std::remove(new_active.begin(), new_active.end(), e.contact), new_active.end());
              state.contact[e.contact].normal_force = 0.0;
              break;
            case EventKind::kRecontact:
              new_active.push_back(e.contact);
              impact = true;
              break;
            case EventKind::kLigamentKink:
              ++result.ligament_kink_crossings;
              break;
          }
        }
        phase_over = true;
        if (done) break;
        std::sort(new_active.begin(), new_active.end());
        state.active = new_active;
        if (impact) ApplyPlasticImpact(model, &state);
        CompleteHiddenConstraint(scene.model, &state);
        // A contact whose consistent force would pull (N < 0) separates at once: drop the
        // most negative one and solve again (e.g. a re-contact that bounces off, or the
        // second compartment unloading as the first lifts off).
        for (;;) {
          int worst = -1;
          for (int i : state.active) {
            if (state.contact[i].normal_force < 0.0 &&
                (worst < 0 || state.contact[i].normal_force < state.contact[worst].normal_force)) {
              worst = i;
            }
          }
          if (worst < 0) break;
          result.events.push_back({StrCat("liftoff_", CompartmentName(model.contacts[worst].compartment)),
                                   state.t, state.q(kAlpha)});
          state.active.erase(std::remove(state.active.begin(), state.active.end(), worst), state.active.end());
          state.contact[worst].normal_force = 0.0;
          CompleteHiddenConstraint(scene.model, &state);
        }
      }
    }
    result.completed = true;
  } catch (const Error& e) {
    result.completed = false;
    result.failure = e.what() + FailureSituation(model, state);
  } catch (const std::exception& e) {  // any other failure while integrating: still partial
    result.completed = false;
    result.failure = StrCat("RunScene(): ", e.what());
  }
  result.stats = formulation->stats();
  result.integrator = formulation->integrator();
  if (result.integrator.empty()) result.integrator = settings.options.integrator;
  result.fixed_step = formulation->fixed_step();
  result.wall_time_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  return result;
}

}  // namespace kneedyn
