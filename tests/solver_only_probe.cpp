// A program linking kneedyn_solver alone (no loader, no formulations): the ctest `layering`
// (tests/layering_test.py) checks with ldd that it pulls in no YAML library, and runs it to
// show the physics library is usable without the loader.
//
// What it runs:
//  1. The chapter's knee built in code with the model builder (solver/model_builder.hpp):
//     the two sphere-on-plane compartments, the twelve elements of Tables 1.1-1.3, the
//     reference pose of docs/model.md §6 and the chapter's published guesses (section 1.4);
//     then the consistent initialization at rest. Checked against docs/model.md §10 (typed
//     from the document, not from this code's output): R0 = (0.164268378, −5.740280083,
//     −214.743856) mm, L0 of ACL posterior 26.675602 mm and of LCL 59.593311 mm, and the
//     consistent initial normal forces 233.35 N and 243.33 N.
//  2. A free tibia (no contacts, no ligaments) under gravity. Exact answer: the centre of
//     mass accelerates at g and the rotations not at all, q̈ = (g, 0, 0, 0).
// Exit 0 when every check holds, 1 otherwise.
#include <cmath>
#include <cstdio>

#include "solver/consistent_init.hpp"
#include "solver/model_builder.hpp"
#include "solver/units.hpp"

namespace {

using namespace kneedyn;

struct Element {
  const char* name;
  double femoral_mm[3], tibial_mm[3], k_linear_N_mm, k_parabolic_N_mm2, extension_ratio;
};
// Tables 1.1-1.3 (docs/model.md §5 on the column headings).
const Element kChapterElements[12] = {
    {"ACL anterior", {7.25, -15.6, 21.25}, {-7.0, 5.0, 211.25}, 83.15, 22.48, 1.000},
    {"ACL posterior", {7.25, -20.3, 19.55}, {2.0, 2.0, 212.25}, 83.15, 26.27, 1.051},
    {"PCL anterior", {-4.75, -11.2, 14.05}, {5.0, -30.0, 206.25}, 125.00, 31.26, 1.004},
    {"PCL posterior", {-4.75, -23.2, 15.65}, {-5.0, -30.0, 206.25}, 60.00, 19.29, 1.050},
    {"MCL anterior", {-34.75, -1.0, 26.25}, {-20.0, 4.0, 171.25}, 91.25, 10.00, 0.940},
    {"MCL oblique", {-34.75, -8.0, 24.25}, {-35.0, -30.0, 199.25}, 27.86, 5.00, 1.031},
    {"MCL deep", {-34.75, -5.0, 21.25}, {-35.0, 0.0, 199.25}, 21.07, 5.00, 1.049},
    {"LCL", {35.25, -15.0, 21.25}, {45.0, -25.0, 176.25}, 72.22, 10.00, 1.050},
    {"capsule medial", {-24.75, -38.0, 6.25}, {-25.0, -25.0, 181.25}, 52.59, 12.00, 1.080},
    {"capsule lateral", {25.25, -35.5, 8.25}, {25.0, -25.0, 181.25}, 54.62, 12.00, 1.080},
    {"oblique popliteal", {25.25, -35.5, 8.25}, {-25.0, -25.0, 181.25}, 21.42, 3.00, 1.080},
    {"arcuate popliteal", {-24.75, -38.0, 6.25}, {25.0, -25.0, 181.25}, 20.82, 3.00, 1.070},
};

Vector3d Mm(const double v[3]) { return Vector3d(v[0], v[1], v[2]) * kMPerMm; }

KneeDescription ChapterKnee() {
  KneeDescription d;
  // Femoral condyles (Eq. 1.4) and tibial plateaus z' = m x' + c (Eq. 1.5), docs/model.md §3.
  const SurfacePair medial{std::make_shared<SphereCap>(Vector3d(-23.75, -18.0, 12.0) * kMPerMm, 21.0e-3),
                           std::make_shared<PlaneSurface>(0.358, 0.0, 213.0e-3)};
  const SurfacePair lateral{std::make_shared<SphereCap>(Vector3d(23.0, -16.0, 11.5) * kMPerMm, 20.0e-3),
                            std::make_shared<PlaneSurface>(-0.341, 0.0, 212.9e-3)};
  d.reference_pose.alpha = 0.0;
  d.reference_pose.beta = kPi / 2.0;
  d.reference_pose.gamma = 0.0;
  d.reference_pose.y0 = -5.740280082863e-3;
  d.reference_pose.medial = medial;
  d.reference_pose.lateral = lateral;
  d.model.mass = 4.0;
  d.model.inertia_T = Vector3d(0.0672, 0.0672, 0.005334);
  d.model.gravity_F = Vector3d(0.0, -9.81, 0.0);
  for (const Element& e : kChapterElements) {
    Ligament lig;
    lig.name = e.name;
    lig.p_FoA_F = Mm(e.femoral_mm);
    lig.p_ToB_T = Mm(e.tibial_mm);
    lig.k_linear = e.k_linear_N_mm * kMmPerM;
    lig.k_parabolic_published = e.k_parabolic_N_mm2 * kMmPerM * kMmPerM;
    lig.extension_ratio = e.extension_ratio;
    d.model.ligaments.push_back(lig);
  }
  for (auto [c, s] : {std::pair{Compartment::kMedial, medial}, std::pair{Compartment::kLateral, lateral}}) {
    ContactPair pair;
    pair.compartment = c;
    pair.femoral_surface = s.femoral;
    pair.tibial_surface = s.tibial;
    d.model.contacts.push_back(pair);
  }
  // Section 1.4's published guesses (mm, N).
  d.initial.guesses = InitialStateRequest::GuessSource::kChapter;
  ChapterContactGuess med, lat;
  med.femoral_xy = {-16.72913866466e-3, -18.540280082863e-3};
  med.tibial_xy = std::array<double, 2>{-16.980955e-3, -12.8e-3};
  med.normal_force = 150.0;
  lat.femoral_xy = {16.50009371e-3, -16.00200022911e-3};
  lat.normal_force = 130.0;
  d.initial.chapter_guesses = {med, lat};
  return d;
}

bool Check(const char* what, double value, double expected, double tolerance) {
  const bool ok = std::abs(value - expected) <= tolerance;
  std::printf("solver_only_probe: %-28s %.9f (docs/model.md §10: %.9f) %s\n", what, value, expected, ok ? "ok" : "FAIL");
  return ok;
}

bool ChapterKneeHolds() {
  const Knee knee = BuildKnee(ChapterKnee());
  bool ok = knee.model.ligaments.size() == 12;
  ok &= Check("reference x0 (mm)", MToMm(knee.reference_q(kX0)), 0.164268378, 5.1e-10);
  ok &= Check("reference z0 (mm)", MToMm(knee.reference_q(kZ0)), -214.743856, 5.1e-7);
  ok &= Check("L0 ACL posterior (mm)", MToMm(knee.model.ligaments[1].slack_length), 26.675602, 5.1e-7);
  ok &= Check("L0 LCL (mm)", MToMm(knee.model.ligaments[7].slack_length), 59.593311, 5.1e-7);
  const MechanicalState s = ConsistentInitialize(knee.model, knee.initial, {0, 1}, ConsistentInitOptions(), nullptr);
  ok &= Check("consistent x0 (mm)", MToMm(s.q(kX0)), 0.164268378, 5.1e-10);
  ok &= Check("consistent z0 (mm)", MToMm(s.q(kZ0)), -214.743856, 5.1e-7);
  ok &= Check("N medial (N)", s.contact[0].normal_force, 233.35, 0.0051);
  ok &= Check("N lateral (N)", s.contact[1].normal_force, 243.33, 0.0051);
  return ok;
}

bool FreeTibiaFallsAtG() {
  Model model;
  model.mass = 4.5;                               // kg
  model.inertia_T = Vector3d(0.07, 0.07, 0.005);  // kg m²
  model.gravity_F = Vector3d(0.0, -9.81, 0.0);    // m/s²
  InitialState initial;
  initial.q << 0.0, -0.2, 0.0, 0.3, M_PI / 2, 0.1;  // β = 90°: away from the JCS singularity
  const MechanicalState s = ConsistentInitialize(model, initial, {}, ConsistentInitOptions(), nullptr);
  const double err = std::max((s.qdd.head<3>() - model.gravity_F).cwiseAbs().maxCoeff(),
                              s.qdd.tail<3>().cwiseAbs().maxCoeff());
  std::printf("solver_only_probe: free tibia, max |qdd - (g, 0)| = %.3g\n", err);
  return err <= 1e-9;
}

}  // namespace

int main() {
  const bool chapter = ChapterKneeHolds();
  const bool free_fall = FreeTibiaFallsAtG();
  return chapter && free_fall ? 0 : 1;
}
