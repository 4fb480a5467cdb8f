// The mechanical state every formulation exchanges with the run driver: pose and rates in
// generalized coordinates plus, per contact pair, the chapter-form contact coordinates and
// the normal force. Formulations keep their own internal state (minimal coordinates,
// Newmark accelerations, IDA vectors) and convert to and from this one.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "solver/initial_state.hpp"
#include "solver/model.hpp"

namespace kneedyn {

struct PatellaGuess;  // patella.hpp

// Which contact description a formulation carries (and so what initialization must solve).
enum class ContactForm {
  kChapter,     // contact coordinates are unknowns (Eqs. 1.8, 1.13)
  kClosedForm,  // sphere-on-plane gap φ(q)
};

struct MechanicalState {
  double t = 0.0;                   // s
  Vector6d q = Vector6d::Zero();    // (x0, y0, z0 [m], α, β, γ [rad])
  Vector6d qd = Vector6d::Zero();   // q̇
  Vector6d qdd = Vector6d::Zero();  // q̈
  std::vector<int> active;          // indices into model.contacts in contact, ascending
  // Per model.contacts entry (index-aligned): the contact coordinates c in its chart
  // (ContactGuess::chart: height-field (xc, yc, x′c, y′c) [m], or the regular charts' angles
  // (uf, vf, ut, vt) [rad], contact.hpp) and normal force N [N]; active contacts only.
  std::vector<ContactGuess> contact;
  // Per model.ligaments entry: the branch locked for the current phase (ligament.hpp);
  // empty = choose by length. Set by the run driver at every phase start.
  std::vector<signed char> ligament_branch;
  // Per model.contacts entry: a separated contact's gap (m) when it separated (for one that
  // starts separated, at the run's first phase); its re-contact is measured from min(gap, 0)
  // at every phase while it stays separated (RecordSeparationGaps, EventsForPhase). NaN while
  // in contact; empty before the first phase.
  std::vector<double> separation_gap;
  // Patella scenes: the patella's equilibrium at the tibial coordinates patella_q, followed
  // from one restart to the next (RestartAcceleration, consistent_init.hpp); null before the
  // first. Replaced, never changed in place: copies of the state may share it.
  std::shared_ptr<const PatellaGuess> patella;
  Vector6d patella_q = Vector6d::Zero();

  bool IsActive(int contact_index) const;
};

}  // namespace kneedyn
