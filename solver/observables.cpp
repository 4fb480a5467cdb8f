#include "solver/observables.hpp"

#include <cmath>

#include "solver/constraint_residuals.hpp"
#include "solver/contact_kinematics.hpp"
#include "solver/dynamics.hpp"
#include "solver/ligament.hpp"
#include "solver/units.hpp"

namespace kneedyn {

EnergyObservables ComputeEnergies(const Model& model, const Vector6d& q, const Vector6d& qd) {
  EnergyObservables e;
  const Vector6d nu = GeneralizedVelocity(q, qd);
  const Vector3d w = nu.tail<3>();
  e.kinetic = 0.5 * model.mass * nu.head<3>().squaredNorm() + 0.5 * w.dot(model.inertia_T.cwiseProduct(w));
  e.load_potential = -(model.mass * model.gravity_F + model.constant_load.force_F).dot(q.head<3>());
  const Pose pose = PoseFromCoordinates(q);
  // The total accumulated in MechanicalEnergy's order, so both give the same bits.
  e.mechanical = e.kinetic;
  e.mechanical -= (model.mass * model.gravity_F + model.constant_load.force_F).dot(q.head<3>());
  for (const Ligament& lig : model.ligaments) {
    const double v = LigamentPotential(lig, LigamentSpan_F(lig, pose).norm());
    e.ligament_potential += v;
    e.mechanical += v;
  }
  return e;
}

void ComputeObservables(const Model& model, const MechanicalState& st, ContactPointSource source,
                        Observables* out, unsigned extras) {
  const Vector6d& q = st.q;
  const Vector6d& qd = st.qd;
  out->t = st.t;
  out->pulse = PulseMagnitude(model.pulse, st.t);
  out->contacts_active = static_cast<int>(st.active.size());
  JointObservables& j = out->joint;
  j.flexion_deg = RadToDeg(q(kAlpha));
  j.valgus_deg = RadToDeg(q(kBeta)) - 90.0;  // β raw, 90° = neutral
  j.external_rotation_deg = RadToDeg(q(kGamma));
  j.flexion_rate_deg_s = RadToDeg(qd(kAlpha));
  j.valgus_rate_deg_s = RadToDeg(qd(kBeta));
  j.external_rotation_rate_deg_s = RadToDeg(qd(kGamma));
  j.omega_T = AngularVelocityT(q, qd);
  out->energy = extras & kObserveEnergies ? ComputeEnergies(model, q, qd) : EnergyObservables();

  const Pose pose = PoseFromCoordinates(q);
  std::vector<double> gap, rate;
  ConstraintResiduals(model, st, &gap, &rate);
  out->contacts.assign(model.contacts.size(), ContactObservables());
  for (size_t i = 0; i < model.contacts.size(); ++i) {
    const ContactPair& pair = model.contacts[i];
    ContactObservables& c = out->contacts[i];
    c.gap = gap[i];
    c.gap_rate = rate[i];
    c.active = st.IsActive(static_cast<int>(i));
    if (!c.active) continue;
    c.normal_force = st.contact[i].normal_force;
    ContactGeometry geo;
    if (source == ContactPointSource::kPose) {
      c.point_found = ContactKinematics(pair, pose, &geo);
    } else {
      double r[5];
      c.point_found = ChapterContactResiduals(pair, pose, st.contact[i].coordinates.data(), r, &geo,
                                              st.contact[i].chart);
    }
    if (c.point_found) {
      c.point_F = geo.point_F;
      c.point_T = geo.point_T;
    }
    ContactGeometry at_q;
    if ((extras & kObserveFemoralSlope) && ContactKinematics(pair, pose, &at_q)) {
      HeightSample hs;
      c.femoral_slope = pair.femoral_surface->Evaluate(at_q.point_F.x(), at_q.point_F.y(), &hs)
                            ? std::hypot(hs.gradient[0], hs.gradient[1])
                            : INFINITY;
    }
  }

  // Each element's length and tension as ComputeAppliedWrench finds them (dynamics.hpp: the
  // span's norm, the law by length, Eq. 1.14), without its wrench sums, its workspace or a
  // patella's equilibrium solve.
  out->ligaments.resize(model.ligaments.size());
  for (size_t k = 0; k < model.ligaments.size(); ++k) {
    const Ligament& lig = model.ligaments[k];
    const double length = LigamentSpan_F(lig, pose).norm();
    out->ligaments[k].length = length;
    out->ligaments[k].strain = LigamentStrain(lig, length);
    out->ligaments[k].tension = LigamentTension(lig, length);
  }
}

}  // namespace kneedyn
