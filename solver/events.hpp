// Event functions shared by every formulation: contact lift-off (N_i crosses zero
// decreasing), re-contact of a separated compartment (gap φ_i crosses zero decreasing) and
// the end condition (α reaches the scene's flexion), plus the internal events where the
// published ligament law jumps (ε_j = 2ε1, docs/model.md §5): a solver must not step across a
// discontinuity, so the driver restarts the formulation there. With a patella (docs/model.md §12),
// the lift-off and re-contact of each patellar facet: the patella is massless, so neither
// is an impact; they restart the formulation where the tendon force's derivative jumps.
// Each formulation locates their roots
// with its own machinery (IDA/CVODE/ARKODE root finding, Newmark step bisection); the
// definitions live here so that every formulation stops at the same events.
#pragma once

#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "solver/contact_kinematics.hpp"
#include "solver/ligament.hpp"
#include "solver/patella.hpp"
#include "solver/pose.hpp"
#include "solver/state.hpp"

namespace kneedyn {

enum class EventKind { kLiftoff, kRecontact, kFlexionEnd, kLigamentKink, kPatellarLiftoff, kPatellarRecontact };

struct EventSpec {
  EventKind kind;
  int contact = -1;   // index into model.contacts (lift-off / re-contact); patellar: the facet (0 medial, 1 lateral)
  int ligament = -1;  // index into model.ligaments (kink)
  int direction = 0;  // −1: root only while decreasing; +1: increasing (SUNDIALS convention)
  double offset = 0.0;  // g = value − offset (re-contact hysteresis, α_end, kink length)
  std::string name;   // "liftoff_lateral", "recontact_medial", "flexion_90", "liftoff_patellar_medial"
  // Patellar events: the warm start of the patella's equilibrium solve, shared by the copies
  // of the phase's specs (the evaluations of one run follow each other on one thread).
  std::shared_ptr<PatellaGuess> patella_guess;
};

// A separated patellar facet re-contacts when its force ratio λ_i reaches this (−, so
// 1e-9 F_Q): the lift-off root leaves λ_i within round-off of zero, and the phase after it
// must not see a re-contact there. A phase starts with a facet pressing when λ_i exceeds
// half of it.
constexpr double kPatellarRecontactRatio = 1.0e-9;

// A separated compartment re-contacts when its gap falls `gap_tolerance` below its value
// at separation (or below zero): keeps integration error from re-closing a contact that
// has just lifted off. The driver sets it from the drift it has observed (≥ 1 nm).
constexpr double kMinRecontactHysteresis = 1.0e-9;  // m

// The events watched during a phase starting at `state` (its active contacts). A separated
// contact's re-contact root is gap − (min(g_sep, 0) − h), h = max(gap_tolerance,
// kMinRecontactHysteresis), g_sep its state.separation_gap (the gap now when there is none);
// should the gap already lie below that line (a tolerance smaller than the last phase's), the
// root starts kMinRecontactHysteresis above zero instead of below it, where it could never cross.
std::vector<EventSpec> EventsForPhase(const Model& model, const EndCondition& end,
                                      const MechanicalState& state,
                                      double gap_tolerance = kMinRecontactHysteresis);

// Keeps state->separation_gap at every phase start: the gap now for a separated contact that
// has none yet (it has just separated, or the run starts with it separated), NaN for an
// active one. A restart while a compartment stays separated (a ligament kink) thus measures
// its re-contact from the gap at separation, not from the restart's: from the restart's,
// each restart on a sinking condyle widened the sinking allowed by another hysteresis.
void RecordSeparationGaps(const Model& model, MechanicalState* state);

// m: how far on the side its locked branch has left (LigamentBranchesAt) a ligament's length
// may start a phase and count as round-off of the restart (a millionth of the kink lengths'
// tens of mm); beyond it the branch and the pose disagree and the root stays as it is.
constexpr double kKinkRoundOff = 1.0e-9;
// m: below it the start length is the kink's to the last bits of a double (~1e-17 m: a
// located root, or the extended-precision reference's state rounded to double for the hand-
// over) and the root is left alone; moving it would displace the law's jump by more than the
// rounding (the conservative scene's energy, conserved to 1e-15 in long double, drifts to
// 1.6e-13 when its kinks move by 1e-14 m).
constexpr double kKinkRoundOffFloor = 1.0e-15;
// m: where such a root is moved to, past the start length on the branch's side; far above
// the last-bit differences of L_j between the code paths that evaluate it (~1e-17 m).
constexpr double kKinkStartMargin = 1.0e-14;

// A phase starts with each ligament locked on the branch its motion is entering, but the
// root that ended the last phase leaves L_j within round-off of the kink, on either side,
// and the restart's projection moves it by ~1e-12 m (−8.5e-13 m on chapter_impact at
// t = 23.4 ms). A kink root that starts on the side the branch has left would cross zero
// again within the first step, a second restart for one crossing from a tiny step. Such a
// root (kKinkRoundOffFloor < |g| ≤ kKinkRoundOff) is measured from the phase's start length
// instead: offset = L_j(q0) ∓ kKinkStartMargin, so g(t0) lies on the branch's side and the
// root watches the next genuine crossing. `state`: the phase's start, its ligament_branch
// locked.
void MeasureKinkRootsFromPhaseStart(const Model& model, const MechanicalState& state,
                                    std::vector<EventSpec>* specs);

// g_k(state) for each spec, in order: N_i (lift-off), φ_i − offset (re-contact), α − offset
// (flexion; offset = α_end), L_j − offset (kink; offset = (1 + 2ε1) L0_j), c_i (patellar
// lift-off) and −c_i − offset (patellar re-contact; offset = −kPatellarRecontactRatio) with c_i
// the facet's contact function (PatellarContactFunction, patella.hpp) of the patella's
// equilibrium at q. `normal_force` is indexed like model.contacts.
// Throws SolverError when a gap has no contact point (contact_kinematics.hpp).
void EvaluateEvents(const Model& model, const std::vector<EventSpec>& specs, const Vector6d& q,
                    const std::vector<double>& normal_force, double* g);
// The same with the pose at q already computed by the caller (e.g. by the constrained solve
// of the same point).
void EvaluateEvents(const Model& model, const std::vector<EventSpec>& specs, const Vector6d& q,
                    const Pose& pose, const std::vector<double>& normal_force, double* g);
// The same with the ligament lengths L_j at `pose` too (DataTpl::ligament_length, filled by
// ComputeAppliedWrench from the same LigamentSpan_F, so the same values): the kink events
// take them instead of recomputing every span.
void EvaluateEvents(const Model& model, const std::vector<EventSpec>& specs, const Vector6d& q,
                    const Pose& pose, const std::vector<double>& normal_force,
                    const std::vector<double>& ligament_length, double* g);

// The patellar facet's contact function c_i at tibial coordinates q (patella.hpp), the
// patella's equilibrium solved from *guess (updated).
double PatellarContactFunctionAt(const Model& model, const Vector6d& q, PatellaGuess* guess, int facet);

// EvaluateEvents in any scalar type (the double overloads above call it); T = long double:
// sphere-on-plane gaps only (RequireContactKinematicsTpl).
template <typename T>
void EvaluateEventsTpl(const Model& model, const std::vector<EventSpec>& specs, const Vector6<T>& q,
                       const PoseTpl<T>& pose, const std::vector<T>& normal_force, T* g,
                       const std::vector<T>* ligament_length = nullptr) {
  for (size_t k = 0; k < specs.size(); ++k) {
    const EventSpec& s = specs[k];
    switch (s.kind) {
      case EventKind::kLiftoff:
        g[k] = normal_force[s.contact];
        break;
      case EventKind::kRecontact:
        g[k] = RequireContactKinematicsTpl(model.contacts[s.contact], pose, "EvaluateEvents").gap - s.offset;
        break;
      case EventKind::kFlexionEnd:
        g[k] = q(kAlpha) - s.offset;
        break;
      case EventKind::kLigamentKink: {
        // The lengths at `pose` when the caller has them (DataTpl::ligament_length), else spans.
        const T length = ligament_length ? (*ligament_length)[s.ligament]
                                         : T(LigamentSpan_F(model.ligaments[s.ligament], pose).norm());
        g[k] = length - s.offset;
        break;
      }
      case EventKind::kPatellarLiftoff:
      case EventKind::kPatellarRecontact: {
        // The patella's solve is in double (patella.hpp).
        Vector6d q_d;
        for (int i = 0; i < 6; ++i) q_d(i) = ScalarPart(q(i));
        const double c = PatellarContactFunctionAt(model, q_d, s.patella_guess.get(), s.contact);
        g[k] = T(s.kind == EventKind::kPatellarLiftoff ? c : -c - s.offset);
        break;
      }
    }
  }
}

// "flexion_90" for 90°; integer degrees when whole, else one decimal.
std::string FlexionEventName(double flexion_rad);
// "liftoff_medial" / "liftoff_lateral": a condyle's lift-off (a patellar facet's is
// liftoff_patellar_<facet>).
inline std::string LiftoffEventName(Compartment c) { return std::string("liftoff_") + CompartmentName(c); }

// The end event whose state the "90°" outcomes (time_90_s, F90_*, N90_*) of sweeps, batches and
// sensitivities read: flexion_90. A scene ending at another flexion has none (they are NaN).
inline const std::string& Flexion90EventName() {
  static const std::string name = FlexionEventName(M_PI / 2.0);
  return name;
}

}  // namespace kneedyn
