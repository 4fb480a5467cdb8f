#include "crosscheck/simbody/simbody_solution.hpp"

#include <cmath>
#include <limits>

#include "solver/error.hpp"
#include "solver/units.hpp"

namespace kneedyn {
namespace simbody {

namespace {
const double kNaN = std::numeric_limits<double>::quiet_NaN();
}  // namespace

bench::Solution ToSolution(const Scene& scene, const Result& result, double interval) {
  const Model& model = scene.model;
  bench::Solution s;
  s.names["positions"] = {"x0_mm", "y0_mm", "z0_mm", "flexion_deg", "valgus_deg", "external_rotation_deg"};
  s.names["velocities"] = {"vx_mm_s", "vy_mm_s", "vz_mm_s", "flexion_rate_deg_s", "valgus_rate_deg_s",
                           "external_rotation_rate_deg_s"};
  for (const ContactPair& pair : model.contacts) {
    for (const char* frame : {"femoral", "tibial"})
      for (const char* axis : {"x", "y", "z"})
        s.names["contact_points"].push_back(StrCat(frame, "_", CompartmentName(pair.compartment), "_", axis, "_mm"));
    s.names["contact_forces"].push_back(StrCat("N_", CompartmentName(pair.compartment), "_N"));
  }
  for (const Ligament& lig : model.ligaments) s.names["ligament_forces"].push_back("F_" + lig.name + "_N");
  for (const std::string& c : bench::VariableClasses()) s.values[c];
  auto append = [&](const Sample& smp) {
    const Vector6d& q = smp.state.q;
    const Vector6d& qd = smp.state.qd;
    s.times.push_back(smp.t);
    s.values["positions"].push_back({MToMm(q(kX0)), MToMm(q(kY0)), MToMm(q(kZ0)), RadToDeg(q(kAlpha)),
                                     RadToDeg(q(kBeta)) - 90.0, RadToDeg(q(kGamma))});
    s.values["velocities"].push_back({MToMm(qd(kX0)), MToMm(qd(kY0)), MToMm(qd(kZ0)), RadToDeg(qd(kAlpha)),
                                      RadToDeg(qd(kBeta)), RadToDeg(qd(kGamma))});
    std::vector<double> points, forces;
    for (size_t i = 0; i < model.contacts.size(); ++i) {
      const bool active = smp.state.IsActive(static_cast<int>(i));
      for (int a = 0; a < 3; ++a) points.push_back(active ? MToMm(smp.point_F[i](a)) : kNaN);
      for (int a = 0; a < 3; ++a) points.push_back(active ? MToMm(smp.point_T[i](a)) : kNaN);
      forces.push_back(active ? smp.state.contact[i].normal_force : 0.0);
    }
    s.values["contact_points"].push_back(points);
    s.values["contact_forces"].push_back(forces);
    s.values["ligament_forces"].push_back(smp.ligament_tension);
  };
  for (const Sample& smp : result.samples) {
    if (smp.is_event) continue;
    const double n = std::round(smp.t / interval);
    if (std::abs(smp.t - n * interval) > 1e-9) continue;
    append(smp);
  }
  const RunResult& run = result.run;
  if (run.completed && !result.samples.empty() && result.samples.back().is_event && run.end_reason != "end_time") {
    append(result.samples.back());
    s.end_is_event = true;
  }
  s.events = run.events;
  return s;
}

}  // namespace simbody
}  // namespace kneedyn
