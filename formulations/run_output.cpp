#include "formulations/run_output.hpp"

#include <dirent.h>
#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <iterator>
#include <limits>
#include <memory>
#include <random>
#include <string_view>
#include <vector>

#include <ceres/version.h>
#include <sundials/sundials_config.h>

#include "formulations/output_file.hpp"
#include "formulations/internal/newmark_scheme.hpp"
#include "formulations/version.hpp"
#include "solver/constrained_dynamics.hpp"
#include "solver/observables.hpp"
#include "solver/error.hpp"
#include "solver/loads.hpp"
#include "solver/units.hpp"
#include "solver/patella.hpp"

namespace kneedyn {
namespace fs = std::filesystem;

namespace {
// A length in a warning's message, to 4 significant digits (0.3359 mm, not 0.33594237911370106).
std::string Rounded(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.4g", v);
  return text;
}

// printf's %.12g through std::to_chars(general, 12) (C++17 [charconv.to.chars]: exactly
// %.*g in the "C" locale; libstdc++'s Ryu printf, ~700 instructions a number).
size_t FormatGeneral12(double v, char (&out)[kTrajectoryNumberChars]) {
  const std::to_chars_result r = std::to_chars(out, out + kTrajectoryNumberChars, v, std::chars_format::general, 12);
  return static_cast<size_t>(r.ptr - out);  // 12 significant digits fit: never errc::value_too_large
}
}  // namespace

size_t FormatTrajectoryNumber(double v, char (&out)[kTrajectoryNumberChars]) {
  // Same bytes as printf's %.12g, ~5 times fewer instructions than std::to_chars(general, 12)
  // for 2^−99 (1.58e-30) ≤ |v| < 1e12 (the columns' values, round-off-sized gaps and residuals
  // included): with X the decimal exponent of |v| and s = 11 − X, N = |v| 10^s is one double
  // product (10^s exact for s ≤ 22; for s > 19 two products, 10^19 then 10^(s−19)), within
  // 2 × 2^-53 N < 2.3e-4 of the exact one, so N rounded to nearest is printf's 12 digits
  // unless its fraction is within 5e-4 of 1/2: those (ties, printf: to even, and near-ties)
  // take FormatGeneral12, as every other |v| does. Then %g's layout: fixed when
  // −4 ≤ X < 12, else d.ddde−XX; no trailing zeros. (callgrind, the default chapter_impact
  // run's 4,424 numbers: ~130 instructions a number against ~150 for the exact 128-bit
  // quotient this replaces and ~700 for to_chars.)
  const double a = std::abs(v);
  // Below 2^−99 the exponent estimate reaches −31, i.e. s = 42, and the scaling would need
  // 10^(42−19): past kPow10, whose last entry is the last exact power of ten.
  if (!(a >= 0x1p-99 && a < 1e12)) {
    if (a != 0.0) return FormatGeneral12(v, out);
    char* o = out;
    if (std::signbit(v)) *o++ = '-';
    *o++ = '0';
    return static_cast<size_t>(o - out);
  }
  static constexpr double kPow10[23] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,  1e8,  1e9,  1e10, 1e11,
                                        1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};
  uint64_t bits;
  std::memcpy(&bits, &a, sizeof bits);
  const int e2 = static_cast<int>(bits >> 52) - 1022;  // a = f 2^e2, f in [0.5, 1)
  // log10(a) is in [(e2 − 1) log10 2, e2 log10 2): X is the floor of the lower end
  // (78913 / 2^18 = log10 2 to 6 digits; >> on a negative int rounds down) or one more.
  int exponent = ((e2 - 1) * 78913) >> 18;  // −30..11 here
  const auto scale = [a](int s) { return s <= 19 ? a * kPow10[s] : a * kPow10[19] * kPow10[s - 19]; };
  int s = 11 - exponent;
  double scaled = scale(s);
  if (scaled >= 1e12) {  // X was one more
    --s;
    ++exponent;
    scaled = scale(s);
  }
  if (!(scaled >= 1e11 && scaled < 1e12)) return FormatGeneral12(v, out);  // a product rounded across
  const double whole = static_cast<double>(static_cast<uint64_t>(scaled));
  const double fraction = scaled - whole;  // exact
  if (std::abs(fraction - 0.5) < 5e-4) return FormatGeneral12(v, out);
  uint64_t digits12 = static_cast<uint64_t>(whole) + (fraction > 0.5 ? 1 : 0);
  if (digits12 == 1000000000000ULL) {  // 9.99…95 → 10: one digit more before the point
    digits12 = 100000000000ULL;
    ++exponent;
  }
  if (exponent >= 12) return FormatGeneral12(v, out);  // 1e12 reached by rounding up
  // The 12 digits as three groups of four, each two pairs from kPairs (g / 100 = g 5243 >> 19
  // for g < 10^4), 16 bytes of '0' after them so that the layout copies fixed widths.
  static constexpr char kPairs[] =
      "00010203040506070809101112131415161718192021222324252627282930313233343536373839"
      "40414243444546474849505152535455565758596061626364656667686970717273747576777879"
      "8081828384858687888990919293949596979899";
  char digits[28];
  const auto head = static_cast<uint32_t>(digits12 / 100000000);
  const auto tail = static_cast<uint32_t>(digits12 - static_cast<uint64_t>(head) * 100000000);
  const uint32_t groups[3] = {head, tail / 10000, tail % 10000};
  for (int g = 0; g < 3; ++g) {
    const uint32_t hundreds = (groups[g] * 5243) >> 19;
    std::memcpy(digits + 4 * g, kPairs + 2 * hundreds, 2);
    std::memcpy(digits + 4 * g + 2, kPairs + 2 * (groups[g] - hundreds * 100), 2);
  }
  std::memset(digits + 12, '0', 16);
  int n = 12;  // significant digits without the trailing zeros (%g drops them)
  while (n > 1 && digits[n - 1] == '0') --n;
  char* o = out;
  if (v < 0.0) *o++ = '-';
  if (exponent < -4) {  // here −31 ≤ X: d[.ddd]e−XX
    o[0] = digits[0];
    o[1] = '.';
    std::memcpy(o + 2, digits + 1, 12);
    o += n > 1 ? n + 1 : 1;
    std::memcpy(o, "e-", 2);
    std::memcpy(o + 2, kPairs + 2 * -exponent, 2);
    o += 4;
  } else if (exponent >= 0) {  // the first X + 1 digits, then '.' and the rest if any
    std::memcpy(o, digits, 12);
    o[exponent + 1] = '.';
    std::memcpy(o + exponent + 2, digits + exponent + 1, 12);
    o += n > exponent + 1 ? n + 1 : exponent + 1;
  } else {  // 0.000ddd: −X − 1 zeros after the point
    std::memcpy(o, "0.000", 5);
    std::memcpy(o + 1 - exponent, digits, 12);
    o += 1 - exponent + n;
  }
  return static_cast<size_t>(o - out);
}

namespace {
constexpr size_t kPatellaColumns = 11;  // patella_shift_mm … tendon_quadriceps_ratio (MakeTrajectoryTable)

// Appends the patella's columns of a row (docs/model.md §12) to *row: its equilibrium at the
// sample's tibial coordinates, followed from the last row's (*from_q, *guess): from its
// solution, or, when the tibia turned by more than 1° since, in steps of at most 1°
// (SolvePatellaAlongTibialPath, as the events follow it). A failed run can stop where the
// equilibrium leaves the trochlear chart, where the straight path from the row before cannot
// follow it although the run's own small steps held on (a row past
// hard/patella_quadriceps_2000N's chart edge,
// tests/patella_test.cpp): that row's patella columns are empty (NaN) and *not_followed
// records its time and the reason; the next row starts from the last equilibrium reached. A
// completed run's row is treated alike (its own steps held on where the path from the row
// before did not): its trajectory stands, and the warning says the columns are missing.
void AppendPatellaColumns(const Patella& p, const MechanicalState& st, Vector6d* from_q,
                          PatellaGuess* guess, std::vector<double>* row,
                          std::vector<std::pair<double, std::string>>* not_followed,
                          std::array<TrajectoryTable::OffPatella, 2>* off_patella) {
  const Vector6d& q = st.q;
  try {
    if ((q - *from_q).tail<3>().cwiseAbs().maxCoeff() <= DegToRad(1.0)) {
      SolvePatella(p, TuberosityInF(p, PoseFromCoordinates(q)), "MakeTrajectoryTable", guess);
    } else {
      SolvePatellaAlongTibialPath(p, *from_q, q, "MakeTrajectoryTable", guess);
    }
  } catch (const SolverError& e) {
    not_followed->emplace_back(st.t, e.what());
    row->resize(row->size() + kPatellaColumns, std::numeric_limits<double>::quiet_NaN());
    return;
  }
  *from_q = q;
  const std::array<double, kPatellaUnknowns>& x = guess->x;
  // A pressing facet's contact point in P against the patella's extent along z (apex to base).
  const double z_low = std::min(p.apex_P.z(), p.base_P.z()), z_high = std::max(p.apex_P.z(), p.base_P.z());
  for (int i = 0; i < 2; ++i) {
    ChartSample on_patella;
    if (!(x[kPatellaFacetRatio + i] > 0.0) ||
        !p.facet[i].tibial_surface->EvaluateChart(x[kPatellaChart + 4 * i + 2], x[kPatellaChart + 4 * i + 3], &on_patella)) {
      continue;
    }
    const double z = on_patella.p.z();
    const double beyond = std::max(z_low - z, z - z_high);
    TrajectoryTable::OffPatella& off = (*off_patella)[i];
    if (beyond > 0.0 && MToMm(beyond) > off.beyond_mm) off = {st.t, MToMm(z), MToMm(beyond)};
  }
  const double quadriceps = QuadricepsMagnitude(p.quadriceps, st.t);
  const std::array<double, kPatellaColumns> columns = {
      MToMm(x[0]),      MToMm(x[1]),      MToMm(x[2]), RadToDeg(x[3]), RadToDeg(x[4]), RadToDeg(x[5]), quadriceps,
      x[kPatellaTendonRatio] * quadriceps, x[kPatellaFacetRatio] * quadriceps,
      x[kPatellaFacetRatio + 1] * quadriceps, x[kPatellaTendonRatio]};
  row->insert(row->end(), columns.begin(), columns.end());
}
}  // namespace

TrajectoryTable MakeTrajectoryTable(const Scene& scene, const RunResult& result) {
  const Model& model = scene.model;
  TrajectoryTable table;
  auto& cols = table.columns;
  cols = {"time_s", "flexion_deg", "valgus_deg", "external_rotation_deg", "x0_mm", "y0_mm",
          "z0_mm", "vx_mm_s", "vy_mm_s", "vz_mm_s", "flexion_rate_deg_s", "valgus_rate_deg_s",
          "external_rotation_rate_deg_s", "omega_x_T_deg_s", "omega_y_T_deg_s", "omega_z_T_deg_s",
          "pulse_N", "contacts_active", "is_event"};
  // One group of columns per contact pair and per ligament of the model, in model order
  // (names by string concatenation: StrCat's stream cost ~2.5 k instructions a name).
  std::vector<std::string> contact_names;
  for (const ContactPair& pair : model.contacts) contact_names.push_back(CompartmentName(pair.compartment));
  for (const std::string& c : contact_names) {
    for (const char* frame : {"femoral", "tibial"}) {
      for (const char* axis : {"x", "y", "z"}) cols.push_back(std::string(frame) + "_" + c + "_" + axis + "_mm");
    }
  }
  for (const std::string& c : contact_names) cols.push_back("N_" + c + "_N");
  for (const Ligament& lig : model.ligaments) cols.push_back("F_" + ColumnSafeName(lig.name) + "_N");
  for (const std::string& c : contact_names) cols.push_back("gap_" + c + "_mm");
  for (const std::string& c : contact_names) cols.push_back("gap_rate_" + c + "_mm_s");
  for (const Ligament& lig : model.ligaments) cols.push_back("L_" + ColumnSafeName(lig.name) + "_mm");
  for (const Ligament& lig : model.ligaments) cols.push_back("strain_" + ColumnSafeName(lig.name));
  // With a patella (docs/model.md §12): its equilibrium at each row's tibial pose.
  if (model.patella) {
    static constexpr const char* kPatellaColumnNames[] = {
        "patella_shift_mm", "patella_anterior_mm", "patella_proximal_mm", "patella_flexion_deg",
        "patella_tilt_deg", "patella_rotation_deg", "quadriceps_N",        "tendon_force_N",
        "N_patella_medial_N", "N_patella_lateral_N", "tendon_quadriceps_ratio"};
    static_assert(std::size(kPatellaColumnNames) == kPatellaColumns, "AppendPatellaColumns writes these columns");
    cols.insert(cols.end(), std::begin(kPatellaColumnNames), std::end(kPatellaColumnNames));
  }

  Observables obs;
  // The patella's equilibrium is followed from the scene's start through the rows' tibial
  // poses (AppendPatellaColumns; a straight solve from the row before failed where the
  // tuberosity moved 26 mm between rows, a 0.01 s, 1e5 N quadriceps half-sine).
  PatellaGuess patella_guess;
  Vector6d patella_q = model.patella ? model.patella->start_q : Vector6d::Zero();
  for (size_t s = 0; s < result.samples.size(); ++s) {
    const MechanicalState& st = result.samples[s];
    ComputeObservables(model, st, ContactPointSource::kStateCoordinates, &obs, kObserveNothingMore);
    const Vector6d& q = st.q;
    const Vector6d& qd = st.qd;
    const JointObservables& j = obs.joint;
    // The row is sized once and filled in column order (no per-value capacity checks): one
    // group per contact pair and per ligament of the model, as the columns.
    if (obs.contacts.size() != model.contacts.size() || obs.ligaments.size() != model.ligaments.size()) {
      Throw<SolverError>("MakeTrajectoryTable", "observables of ", obs.contacts.size(), " contacts and ",
                         obs.ligaments.size(), " ligaments for a model of ", model.contacts.size(), " and ",
                         model.ligaments.size());
    }
    std::vector<double> row;
    row.reserve(cols.size());
    row.resize(cols.size() - (model.patella ? kPatellaColumns : 0));
    // The values and the names above are two lists in one order: a value without its name
    // would shift every later value under the wrong name (a test of a new column found its
    // strain written under V_ and 0 under strain_). `put` refuses a value past the row's
    // columns, and the count is checked at the end: either way the run stops, naming both.
    double* out = row.data();
    double* const end = row.data() + row.size();
    const auto put = [&out, end](double v) {
      if (out == end) Throw<Error>("MakeTrajectoryTable", "more values than columns: the names and the values must be added together");
      *out++ = v;
    };
    for (double v : {obs.t, j.flexion_deg, j.valgus_deg, j.external_rotation_deg, MToMm(q(kX0)), MToMm(q(kY0)),
                     MToMm(q(kZ0)), MToMm(qd(kX0)), MToMm(qd(kY0)), MToMm(qd(kZ0)), j.flexion_rate_deg_s,
                     j.valgus_rate_deg_s, j.external_rotation_rate_deg_s}) {
      put(v);
    }
    for (int i = 0; i < 3; ++i) put(RadToDeg(j.omega_T(i)));
    put(obs.pulse);
    put(static_cast<double>(obs.contacts_active));
    put(result.sample_is_event[s] ? 1.0 : 0.0);
    for (const ContactObservables& c : obs.contacts) {  // NaN = empty when separated
      for (int a = 0; a < 3; ++a) put(MToMm(c.point_F(a)));
      for (int a = 0; a < 3; ++a) put(MToMm(c.point_T(a)));
    }
    for (const ContactObservables& c : obs.contacts) put(c.normal_force);
    for (const LigamentObservables& l : obs.ligaments) put(l.tension);
    for (const ContactObservables& c : obs.contacts) put(MToMm(c.gap));
    for (const ContactObservables& c : obs.contacts) put(MToMm(c.gap_rate));
    for (const LigamentObservables& l : obs.ligaments) put(MToMm(l.length));
    for (const LigamentObservables& l : obs.ligaments) put(l.strain);
    if (out != end) {
      Throw<Error>("MakeTrajectoryTable", "wrote ", out - row.data(), " values for ", row.size(),
                   " columns before the patella's: the names and the values must be added together");
    }
    if (model.patella) {
      AppendPatellaColumns(*model.patella, st, &patella_q, &patella_guess, &row,
                           &table.patella_not_followed, &table.patella_contact_off);
    }
    table.rows.push_back(std::move(row));
  }
  return table;
}

namespace {
// The largest finite |value| of column c over the table's rows; 0 for a column it lacks.
double LargestMagnitude(const TrajectoryTable& table, size_t c) {
  double largest = 0.0;
  for (const std::vector<double>& row : table.rows) {
    if (c < row.size() && std::isfinite(row[c])) largest = std::max(largest, std::abs(row[c]));
  }
  return largest;
}
}  // namespace

std::vector<OutputWarning> OutputWarnings(const TrajectoryTable& table, const RunResult& result) {
  std::vector<OutputWarning> out;
  const auto& cols = table.columns;
  const auto column = [&](const char* name) {
    return static_cast<size_t>(std::find(cols.begin(), cols.end(), name) - cols.begin());
  };
  const size_t time_col = column("time_s"), event_col = column("is_event");
  for (size_t c = 0; c < cols.size(); ++c) {
    const std::string& name = cols[c];
    // N_<compartment>_N (tibial) and N_patella_<facet>_N; not the ligaments' F_*_N.
    if (name.size() < 5 || name.compare(0, 2, "N_") != 0 || name.compare(name.size() - 2, 2, "_N") != 0) continue;
    const std::string which = name.substr(2, name.size() - 4);  // "medial", "patella_lateral"
    const bool facet = which.compare(0, 8, "patella_") == 0;
    const std::string part = facet ? which.substr(8) : which;
    const std::string liftoff = facet ? "liftoff_patellar_" + part : "liftoff_" + part;
    // The contact's own lift-off row holds the event location's error, −1e-15 to −2e-11 N
    // (dae, staggered); far more is a lift-off the method did not locate (newmark
    // halving its step before a failure recorded one at -3.9 N of 2.2 kN, hard/patella_quadriceps_2000N).
    const double largest = LargestMagnitude(table, c);
    const double located = kLiftoffRowForceFraction * largest;
    double min_force = 0.0, at = 0.0;
    for (const std::vector<double>& row : table.rows) {
      if (c >= row.size() || !(row[c] < min_force)) continue;
      if (event_col < row.size() && row[event_col] == 1.0 && row[c] >= -located) {
        const bool own_liftoff = std::any_of(result.events.begin(), result.events.end(), [&](const EventRecord& e) {
          return e.name == liftoff && e.time == row[time_col];
        });
        if (own_liftoff) continue;
      }
      min_force = row[c];
      at = row[time_col];
    }
    if (!(min_force < -kPullingForceFloorN)) continue;
    OutputWarning p;
    p.kind = "pulling_contact";
    p.column = name;
    p.contact = (facet ? "patellar facet " : "tibial contact ") + part;
    p.min_force_N = min_force;
    p.time_s = at;
    p.message = StrCat("the ", p.contact, " pulled: ", name, " = ", min_force, " N at t = ", at, " s (its minimum",
                       facet ? "; without patella.facet_liftoff both facets stay in contact with a force of either "
                               "sign, docs/model.md §12; facet_liftoff: true separates a pulling facet)"
                             : "; a tibial contact separates at its lift-off event, docs/model.md §9: this row "
                               "lies past a lift-off the integration did not locate)");
    out.push_back(std::move(p));
  }
  for (const auto& [time, why] : table.patella_not_followed) {
    OutputWarning p;
    p.kind = "patella_not_followed";
    p.time_s = time;
    p.message = StrCat("the patella's columns are empty at t = ", time, " s: its equilibrium, followed from the row "
                       "before, was not reached at this row's tibial pose",
                       result.completed ? ", which the run's own steps reached (" : ", where the run stopped (", why, ")");
    out.push_back(std::move(p));
  }
  for (int i = 0; i < 2; ++i) {
    const TrajectoryTable::OffPatella& off = table.patella_contact_off[i];
    if (std::isnan(off.time_s)) continue;
    OutputWarning p;
    p.kind = "patella_contact_off";
    p.contact = StrCat("patellar facet ", i == 0 ? "medial" : "lateral");
    p.time_s = off.time_s;
    p.message = StrCat("the ", p.contact, "'s contact lies off the patella: z = ", off.z_P_mm, " mm in P at t = ",
                       off.time_s, " s, ", off.beyond_mm, " mm beyond its extent from patella.apex_P_mm to base_P_mm "
                       "(the facets are unbounded planes, docs/model.md §12); check patella.tuberosity_T_mm, "
                       "tendon_length_mm and the facet planes");
    out.push_back(std::move(p));
  }
  // An output interval as long as the run leaves rows at the start, the events and the end
  // alone: constraint_residuals (over output rows) and every peak taken from the rows then
  // see almost nothing of the run (--output-interval 10 on the chapter scene: the gap rate
  // read 8.7e-6 mm/s where 5 ms rows show 1.2e-4).
  if (table.rows.size() > 1) {
    size_t uniform = 0;
    for (size_t r = 1; r < table.rows.size(); ++r) uniform += table.rows[r][event_col] == 0.0;
    const double span = table.rows.back()[time_col] - table.rows.front()[time_col];
    if (uniform < kMinOutputRows && span > 0.0) {
      OutputWarning p;
      p.kind = "sparse_output";
      p.time_s = table.rows.front()[time_col];
      p.message = StrCat("the output interval left ", uniform, " row(s) besides the start and the events over ", span,
                         " s: constraint_residuals and peaks are taken over the rows written; give a shorter "
                         "--output-interval (or output.interval_s) to see the run");
      out.push_back(std::move(p));
    }
  }
  // The consistent start closes the chapter form's contact equations (points on both surfaces
  // with aligned normals, docs/model.md §4); the gap column is the general kernel's distance.
  // They agree to round-off when the pair has one such point pair; a condyle flatter than its
  // plateau has several, and the start can sit on one that is not the nearest (0.3 mm apart
  // on an ellipsoidal condyle of semi-axes 30, 40, 21 mm). Not the chapter's unprojected start,
  // whose gaps are its guesses'.
  if (!table.rows.empty() && result.init.form.find("unprojected") == std::string::npos) {
    for (size_t c = 0; c < cols.size(); ++c) {
      const std::string& name = cols[c];
      if (name.compare(0, 4, "gap_") != 0 || name.compare(0, 9, "gap_rate_") == 0) continue;
      const double gap_mm = table.rows.front()[c];
      if (!(std::abs(gap_mm) > kStartGapToleranceMm)) continue;  // NaN: not in contact
      OutputWarning p;
      p.kind = "start_not_at_nearest_points";
      p.contact = StrCat("tibial contact ", name.substr(4, name.size() - 7));
      p.column = name;
      p.time_s = table.rows.front()[time_col];
      p.message = StrCat("the ", p.contact, " starts with a gap of ", gap_mm, " mm between its nearest points, ",
                         "although the consistent initialization closed its contact equations (form ",
                         result.init.form, "): the surfaces touch at more than one pair of points with aligned ",
                         "normals (a condyle flatter than its plateau?) and the start sits on one that is not the ",
                         "nearest; another formulation's start may differ (docs/model.md §4)");
      out.push_back(std::move(p));
    }
  }
  // A separated condyle re-contacts when its gap falls below the hysteresis (docs/model.md §9),
  // 10 × max(drift, tolerances). A drift-set hysteresis can let it sink into its plateau,
  // silently, by more than the tolerances allow (ede euler at its default step: 0.34 mm with a
  // 0.48 mm hysteresis from a 0.048 mm drift): the penetration is the drift's, not the knee's.
  if (result.max_recontact_gap_tolerance > result.max_recontact_gap_tolerance_of_tolerances) {
    for (size_t c = 0; c < cols.size(); ++c) {
      const std::string& name = cols[c];
      if (name.compare(0, 4, "gap_") != 0 || name.compare(0, 9, "gap_rate_") == 0) continue;
      const std::string part = name.substr(4, name.size() - 7);
      const size_t point = column(("tibial_" + part + "_x_mm").c_str());
      if (point == cols.size()) continue;
      double deepest_mm = 0.0, at_s = 0.0;
      for (const std::vector<double>& row : table.rows) {  // separated rows: no contact point
        if (std::isnan(row[point]) && row[c] < deepest_mm) deepest_mm = row[c], at_s = row[time_col];
      }
      const double allowed_mm = MToMm(result.max_recontact_gap_tolerance_of_tolerances);
      if (!(-deepest_mm > allowed_mm)) continue;
      OutputWarning p;
      p.kind = "separated_contact_penetrates";
      p.contact = StrCat("tibial contact ", part);
      p.column = name;
      p.time_s = at_s;
      p.message = StrCat("the ", p.contact, ", separated, penetrates its plateau by ", Rounded(-deepest_mm), " mm at t = ", at_s,
                         " s without re-contacting: the re-contact hysteresis (docs/model.md §9) grew to ",
                         Rounded(MToMm(result.max_recontact_gap_tolerance)), " mm with the run's constraint drift, past the ",
                         Rounded(allowed_mm), " mm its tolerances give; a smaller --step or tighter tolerances shrink the drift");
      out.push_back(std::move(p));
    }
  }
  // An element stretched to twice its slack length or more: the pose is none a knee takes (an
  // assembled start far from the chapter's, a diverged run), whatever the solver met.
  for (size_t c = 0; c < cols.size(); ++c) {
    const std::string& name = cols[c];
    if (name.compare(0, 7, "strain_") != 0) continue;
    double largest = kMaxPlausibleStrain, at_s = 0.0;
    for (const std::vector<double>& row : table.rows) {
      if (row[c] > largest) largest = row[c], at_s = row[time_col];
    }
    if (!(largest > kMaxPlausibleStrain)) continue;
    OutputWarning p;
    p.kind = "ligament_overstretched";
    p.column = name;
    p.contact = name.substr(7);
    p.time_s = at_s;
    p.message = StrCat("element ", p.contact, " reaches a strain of ", Rounded(largest), " at t = ", at_s,
                       " s (its length ", Rounded(largest + 1.0), " times its slack length), past ", kMaxPlausibleStrain,
                       ": no ligament stretches so far; check the scene's initial_state and geometry, or, if the "
                       "integration diverged (a fixed step too long for the scene), a smaller --step");
    out.push_back(std::move(p));
  }
  // A fixed-step method cannot resolve a contact phase of a few steps: in the index-3 forms
  // (newmark undamped, generalized-alpha at rho_inf near 1) the normal force oscillates
  // through zero, so such a lift-off and re-contact is taken for a numerical artifact until a
  // smaller --step keeps it (README, "Running").
  if (result.fixed_step > 0.0) {
    for (size_t i = 0; i < result.events.size(); ++i) {
      const EventRecord& a = result.events[i];
      const bool liftoff = a.name.compare(0, 8, "liftoff_") == 0;
      if (!liftoff && a.name.compare(0, 10, "recontact_") != 0) continue;
      const std::string part = a.name.substr(liftoff ? 8 : 10);
      const std::string next = (liftoff ? "recontact_" : "liftoff_") + part;
      const auto b = std::find_if(result.events.begin() + i + 1, result.events.end(),
                                  [&](const EventRecord& e) { return e.name == next; });
      if (b == result.events.end() || b->time - a.time >= kMinResolvedSteps * result.fixed_step) continue;
      // A re-contact that bounces off lifts off at the same instant (its consistent force would
      // pull, docs/model.md §9), in the adaptive methods too: a plastic impact, not a phase a
      // smaller step could resolve.
      if (!liftoff && b->time == a.time) continue;
      OutputWarning p;
      p.kind = "short_contact_phase";
      p.contact = part;
      p.time_s = a.time;
      p.duration_s = b->time - a.time;
      char text[512];  // the longest, with patellar facet names, is ~390 characters
      std::snprintf(text, sizeof(text),
                    "%s at t = %.6f s and %s %.3g s later: %s of %.1f fixed steps (h = %g s), shorter than %d "
                    "steps: likely the normal force oscillating through zero, not a resolved %s; check it with "
                    "another formulation (dae) or, for generalized-alpha, a smaller --step",
                    a.name.c_str(), a.time, next.c_str(), p.duration_s, liftoff ? "a separation" : "a contact phase",
                    p.duration_s / result.fixed_step, result.fixed_step, kMinResolvedSteps,
                    liftoff ? "separation" : "contact phase");
      p.message = text;
      out.push_back(std::move(p));
    }
  }
  // A lift-off is the knee's when its contact force, solved with the contact kept at the event
  // state, is zero there; a method whose own force N oscillates from step to step (newmark's
  // undamped index-3 modes) crosses zero early, and the events after it follow from that.
  for (const EventRecord& e : result.events) {
    if (e.name.compare(0, 8, "liftoff_") != 0 || !std::isfinite(e.consistent_normal_force)) continue;
    const std::string part = e.name.substr(8);
    const std::string name = "N_" + part + "_N";
    const size_t c = column(name.c_str());
    const double largest = LargestMagnitude(table, c);
    if (!(largest > 0.0 && std::abs(e.consistent_normal_force) > kLiftoffConsistentForceFraction * largest)) continue;
    OutputWarning p;
    p.kind = "liftoff_force_not_zero";
    p.contact = "tibial contact " + part;
    p.column = name;
    p.force_N = e.consistent_normal_force;
    p.time_s = e.time;
    p.message = StrCat(e.name, " at t = ", Rounded(e.time), " s: the knee's normal force there, solved again with the "
                       "contact kept, is ", Rounded(e.consistent_normal_force), " N, ",
                       Rounded(100.0 * std::abs(e.consistent_normal_force) / largest), " % of the contact's largest (",
                       Rounded(largest), " N), not 0: the method's own force crossed zero before the knee's (likely an "
                       "oscillating multiplier), so this lift-off is early or spurious (a later one may be the knee's). "
                       "Compare with another formulation (dae); a smaller --step helps generalized-alpha, not newmark "
                       "(docs/outputs.md)");
    out.push_back(std::move(p));
  }
  return out;
}

// The JSON objects below are filled member by member: a braced list of {key, value} pairs
// builds a two-element array per member first (an allocation or three more a member;
// SummaryJson 0.20 -> 0.11 M instructions, callgrind). Keys are sorted by nlohmann::json
// either way, so the bytes are the same.
nlohmann::json StatsJson(const SolverStats& s) {
  nlohmann::json j = nlohmann::json::object();
  j["steps"] = s.steps;
  j["residual_evaluations"] = s.residual_evaluations;
  j["jacobian_evaluations"] = s.jacobian_evaluations;
  j["linear_solver_setups"] = s.linear_solver_setups;
  j["nonlinear_iterations"] = s.nonlinear_iterations;
  j["error_test_failures"] = s.error_test_failures;
  j["convergence_failures"] = s.convergence_failures;
  j["step_halvings"] = s.step_halvings;
  j["rejected_steps"] = s.rejected_steps();
  j["root_evaluations"] = s.root_evaluations;
  j["projections"] = s.projections;
  j["restarts"] = s.restarts;
  return j;
}

namespace {

// The Newton matrix the run used (--jacobian; exact when not given), or null for a
// formulation that forms none of its own (FormulationInfo::jacobians empty).
nlohmann::json JacobianSetting(const RunSettings& settings) {
  const FormulationInfo& info = FindFormulation(settings.formulation);
  if (info.jacobians.empty()) return nullptr;
  return OptionName(settings.options.jacobian.value_or(JacobianKind::kExact));
}

// The IDA Newton systems' solver (--linear-solver; structured when not given), or null for a
// formulation without one (FormulationInfo::linear_solvers empty).
nlohmann::json LinearSolverSetting(const RunSettings& settings) {
  const FormulationInfo& info = FindFormulation(settings.formulation);
  if (info.linear_solvers.empty()) return nullptr;
  return OptionName(settings.options.linear_solver.value_or(LinearSolverKind::kStructured));
}


nlohmann::json LevelJson(const InitLevelReport& r) {
  const char* method = r.method == InitMethod::kNewton ? "newton" : r.method == InitMethod::kCeres ? "ceres" : "none";
  nlohmann::json j = nlohmann::json::object();
  j["residual_before"] = r.residual_before;
  j["residual_after"] = r.residual_after;
  j["iterations"] = r.iterations;
  j["method"] = method;
  return j;
}

nlohmann::json StateJson(const Scene& scene, const MechanicalState& st) {
  nlohmann::json j;
  j["time_s"] = st.t;
  j["flexion_deg"] = RadToDeg(st.q(kAlpha));
  j["valgus_deg"] = RadToDeg(st.q(kBeta)) - 90.0;
  j["external_rotation_deg"] = RadToDeg(st.q(kGamma));
  j["R0_mm"] = {MToMm(st.q(0)), MToMm(st.q(1)), MToMm(st.q(2))};
  j["v_mm_s"] = {MToMm(st.qd(0)), MToMm(st.qd(1)), MToMm(st.qd(2))};
  j["angle_rates_deg_s"] = {RadToDeg(st.qd(3)), RadToDeg(st.qd(4)), RadToDeg(st.qd(5))};
  nlohmann::json contacts = nlohmann::json::object();
  for (size_t i = 0; i < scene.model.contacts.size(); ++i) {
    const std::string name = CompartmentName(scene.model.contacts[i].compartment);
    nlohmann::json& c = contacts[name];
    c["active"] = st.IsActive(static_cast<int>(i));
    c["normal_force_N"] = st.IsActive(static_cast<int>(i)) ? st.contact[i].normal_force : 0.0;
  }
  j["contacts"] = std::move(contacts);
  return j;
}

// The files a run writes, and the score `kneedyn score` writes beside the trajectory by
// default: it scores the set's trajectory, so it goes when the set is replaced.
const char* const kOutputFiles[] = {"trajectory.csv", "trajectory.sto", "summary.json", "trajectory.score.json"};

// `path` holds the pieces one after the other (written as they are: a large piece goes to
// the file without a copy).
void WriteFile(const std::string& dir_name, const fs::path& path, std::initializer_list<std::string_view> pieces) {
  std::ofstream out(path, std::ios::binary);
  if (!out) {
    Throw<InputError>("WriteRunOutputs", "--out = '", EchoPath(dir_name), "': cannot write '",
                      EchoPath(path.string()), "'");
  }
  for (const std::string_view piece : pieces) out.write(piece.data(), static_cast<std::streamsize>(piece.size()));
  out.close();
  if (!out) {
    Throw<InputError>("WriteRunOutputs", "--out = '", EchoPath(dir_name), "': failed writing '",
                      EchoPath(path.string()), "'");
  }
}

// --out without a trailing '/', so that parent_path() and filename() name the directory.
fs::path OutputPath(const std::string& dir_name) {
  fs::path out = fs::path(dir_name).lexically_normal();
  if (out.filename().empty()) out = out.parent_path();
  if (out.empty() || out == out.root_path() || out.filename() == "." || out.filename() == "..") {
    Throw<InputError>("WriteRunOutputs", "--out = '", EchoPath(dir_name),
                      "': must name a directory of its own (not '.', '..' or '/')");
  }
  return out;
}

std::string TempPrefix(const fs::path& out) { return "." + out.filename().string() + ".kneedyn-tmp-"; }

// Removes temporaries of earlier runs into `out` whose process no longer exists.
void RemoveStaleTemporaries(const fs::path& out) {
  const std::string prefix = TempPrefix(out);
  const fs::path parent = out.parent_path().empty() ? fs::path(".") : out.parent_path();
  // readdir and a prefix compare on the raw name: a std::filesystem::directory_iterator costs
  // ~2.6 k instructions an entry (path objects), which in a busy parent such as /tmp was a
  // sizeable share of a short run (callgrind).
  DIR* dir = ::opendir(parent.c_str());
  if (dir == nullptr) return;
  std::vector<std::string> stale;
  while (const dirent* entry = ::readdir(dir)) {
    // The prefix starts with '.': most names fail on their first byte, without a call.
    if (entry->d_name[0] != '.' || std::strncmp(entry->d_name, prefix.c_str(), prefix.size()) != 0) continue;
    const long pid = std::strtol(entry->d_name + prefix.size(), nullptr, 10);
    if (pid <= 0 || pid == ::getpid()) continue;
    if (::kill(static_cast<pid_t>(pid), 0) == -1 && errno == ESRCH) stale.emplace_back(entry->d_name);
  }
  ::closedir(dir);
  for (const std::string& name : stale) {
    std::error_code ignored;
    fs::remove_all(parent / name, ignored);
  }
}

}  // namespace

// A run creates its temporary beside `out` (creating the missing parents first) and, when
// `out` exists, moves the previous set out of the way and deletes it. Both are checked here,
// before the run, so that a refused --out costs no integration and leaves nothing behind:
// deleting the previous set needs write permission on `out` itself (a set published into a
// read-only directory could otherwise be swapped aside and then never removed), and the
// nearest existing ancestor must take a new directory, which a probe directory (created and
// removed at once) shows where permissions alone cannot (e.g. /proc, read-only mounts).
namespace {

void CheckOutputWritable(const std::string& dir_name, const fs::path& out, bool exists) {
  if (exists && ::access(out.c_str(), W_OK | X_OK) != 0) {
    Throw<InputError>("WriteRunOutputs", "--out = '", EchoPath(dir_name), "': ", std::strerror(errno),
                      "; a run replaces the directory and its files, so it must be writable");
  }
  std::error_code ec;
  const fs::path ancestor = NearestExistingAncestor(out);  // where the run creates the missing levels
  if (!fs::is_directory(ancestor, ec)) {
    Throw<InputError>("WriteRunOutputs", "--out = '", EchoPath(dir_name), "': '", EchoPath(ancestor.string()),
                      "' is not a directory");
  }
  const fs::path probe = ancestor / StrCat(TempPrefix(out), ::getpid(), "-probe");
  if (::mkdir(probe.c_str(), 0700) != 0 && errno != EEXIST) {
    Throw<InputError>("WriteRunOutputs", "--out = '", EchoPath(dir_name), "': cannot create a directory in '",
                      EchoPath(ancestor.string()), "' (", std::strerror(errno), ")");
  }
  ::rmdir(probe.c_str());
}

}  // namespace

void CheckOutputDirectory(const std::string& dir_name) {
  const fs::path out = OutputPath(dir_name);
  std::error_code ec;
  const fs::file_status st = fs::symlink_status(out, ec);
  if (ec && ec != std::errc::no_such_file_or_directory) {
    Throw<InputError>("WriteRunOutputs", "--out = '", EchoPath(dir_name), "': ", ec.message());
  }
  if (!fs::exists(st)) return CheckOutputWritable(dir_name, out, /*exists=*/false);
  if (!fs::is_directory(st)) {
    Throw<InputError>("WriteRunOutputs", "--out = '", EchoPath(dir_name), "' exists and is not a directory");
  }
  for (fs::directory_iterator it(out, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    const bool known = std::find(std::begin(kOutputFiles), std::end(kOutputFiles), name) != std::end(kOutputFiles);
    if (!known || !it->is_regular_file()) {
      Throw<InputError>("WriteRunOutputs", "--out = '", EchoPath(dir_name), "' holds '", Echo(name),
                        "', which is not ", known ? "a regular file" : "part of an output set",
                        "; a run replaces the whole directory: give a new or empty one");
    }
  }
  if (ec) Throw<InputError>("WriteRunOutputs", "--out = '", EchoPath(dir_name), "': ", ec.message());
  CheckOutputWritable(dir_name, out, /*exists=*/true);
}

namespace {

// Replaces `out` by `tmp` in one step; afterwards `tmp` holds the previous set (if any).
void Publish(const fs::path& tmp, const fs::path& out) {
  for (int attempt = 0; attempt < 100; ++attempt) {
    if (::renameat2(AT_FDCWD, tmp.c_str(), AT_FDCWD, out.c_str(), RENAME_NOREPLACE) == 0) return;
    if (errno != EEXIST) break;
    if (::renameat2(AT_FDCWD, tmp.c_str(), AT_FDCWD, out.c_str(), RENAME_EXCHANGE) == 0) return;
    if (errno != ENOENT) break;  // ENOENT: `out` vanished in between (another run); again
  }
  Throw<InputError>("WriteRunOutputs", "--out = '", EchoPath(out.string()), "': cannot publish '",
                    EchoPath(tmp.string()), "' as it: ", std::strerror(errno));
}
}  // namespace

nlohmann::json SummaryJson(const Scene& scene, const RunSettings& settings, const RunResult& result,
                           const std::vector<OutputWarning>& warnings) {
  nlohmann::json j;
  j["schema_version"] = kSummarySchemaVersion;  // docs/outputs.md
  j["kneedyn_version"] = KneedynVersion();
  j["git_commit"] = KneedynGitCommit();
  j["command_line"] = settings.command_line;
  j["status"] = result.completed ? "completed" : "partial";
  if (!result.completed) j["failure"] = result.failure;
  j["end_reason"] = result.end_reason;
  nlohmann::json& scene_json = j["scene"];
  scene_json["name"] = scene.name;
  scene_json["path"] = scene.path;
  scene_json["parameter_set"] = scene.parameter_set;
  // The file read, absolute: a copy of a set keeps its name, and a relative path that misses
  // the copy beside the scene falls back to the shipped set (scene/scene.cpp).
  scene_json["parameter_set_file"] =
      scene.parameter_set_file.empty() ? nlohmann::json(nullptr)
                                       : nlohmann::json(fs::absolute(scene.parameter_set_file).lexically_normal().string());
  scene_json["ligaments"] = scene.model.ligaments.size();
  scene_json["contacts"] = scene.model.contacts.size();
  nlohmann::json& pulse = scene_json["pulse"];
  pulse["shape"] = PulseShapeName(scene.model.pulse.shape);
  pulse["amplitude_N"] = scene.model.pulse.amplitude;
  pulse["duration_s"] = scene.model.pulse.duration;
  pulse["peak_factor"] = PulsePeakFactor(scene.model.pulse.shape);  // max Fe / A (solver/loads.hpp)
  scene_json["ligament_law"] = LigamentLawName(scene.model.ligament_law);
  // Named only when it is not the default, so that default runs keep their summary.
  if (scene.model.angular_velocity_map == AngularVelocityMapReading::kPrintedEq1_20b) {
    j["scene"]["angular_velocity_map"] = "printed_eq_1_20b";
  }
  const FormulationOptions& o = settings.options;
  j["formulation"] = settings.formulation;
  // What ran: the integrator and step actually used; adaptive runs record their mean step.
  const double span = result.samples.size() > 1 ? result.samples.back().t - result.samples.front().t : 0.0;
  nlohmann::json& settings_json = j["settings"];
  settings_json["rtol"] = o.rtol;
  settings_json["atol"] = o.atol;
  settings_json["integrator"] = result.integrator;
  settings_json["step_mode"] = result.fixed_step > 0.0 ? "fixed" : "adaptive";
  settings_json["step_s"] = result.fixed_step > 0.0 ? nlohmann::json(result.fixed_step) : nlohmann::json(nullptr);
  settings_json["mean_step_s"] = result.stats.steps > 0 && span > 0.0
                                     ? nlohmann::json(span / static_cast<double>(result.stats.steps))
                                     : nlohmann::json(nullptr);
  nlohmann::json& requested = settings_json["requested"];
  requested["integrator"] = o.integrator ? OptionName(*o.integrator) : "";
  requested["step_s"] = o.step;
  settings_json["max_step_s"] = o.max_step;
  settings_json["max_steps"] = o.max_steps;
  // The scheme a generalized-alpha run used (Chung–Hulbert's from ρ∞, or the four given).
  const FormulationInfo* info = RegisteredFormulation(settings.formulation);
  if (info != nullptr && info->scheme_parameters) {
    const bool explicit_scheme = o.alpha_m.has_value();
    const NewmarkScheme scheme = explicit_scheme ? NewmarkScheme{*o.alpha_m, *o.alpha_f, *o.newmark_beta, *o.newmark_gamma}
                                                 : ChungHulbertScheme(o.rho_inf);
    settings_json["generalized_alpha"] = {{"rho_inf", explicit_scheme ? nlohmann::json(nullptr) : nlohmann::json(o.rho_inf)},
                                          {"alpha_m", scheme.alpha_m},
                                          {"alpha_f", scheme.alpha_f},
                                          {"beta", scheme.beta},
                                          {"gamma", scheme.gamma}};
  } else {
    settings_json["generalized_alpha"] = nullptr;
  }
  settings_json["stabilization"] = OptionName(o.stabilization);
  settings_json["baumgarte_gains_1_s"] = o.stabilization == Stabilization::kBaumgarte
                                             ? nlohmann::json{{"alpha", o.baumgarte_alpha}, {"beta", o.baumgarte_beta}}
                                             : nlohmann::json(nullptr);
  settings_json["constraint_level"] = OptionName(o.constraint_level);
  settings_json["jacobian"] = JacobianSetting(settings);
  settings_json["linear_solver"] = LinearSolverSetting(settings);
  settings_json["contact_chart"] = OptionName(o.contact_chart);
  settings_json["output_interval_s"] = settings.output_interval > 0 ? settings.output_interval : scene.output_interval;
  const InitReport& ir = result.init;
  nlohmann::json forces_guess = nlohmann::json::object(), forces = nlohmann::json::object();
  for (size_t i = 0; i < scene.model.contacts.size() && i < ir.normal_force.size(); ++i) {
    const std::string name = CompartmentName(scene.model.contacts[i].compartment);
    forces_guess[name] = ir.normal_force_guess[i];
    forces[name] = ir.normal_force[i];
  }
  nlohmann::json& init = j["initialization"];
  init["form"] = ir.form;
  init["held"] = ir.held;
  init["position"] = LevelJson(ir.position);
  init["velocity"] = LevelJson(ir.velocity);
  init["hidden_constraint"] = LevelJson(ir.hidden);
  init["normal_force_guess_N"] = std::move(forces_guess);
  init["normal_force_N"] = std::move(forces);
  nlohmann::json events = nlohmann::json::array();
  for (const EventRecord& e : result.events) {
    nlohmann::json event = nlohmann::json::object();
    event["name"] = e.name;
    event["time"] = e.time;
    event["flexion_deg"] = RadToDeg(e.flexion);
    events.push_back(std::move(event));
  }
  j["events"] = std::move(events);
  if (!result.samples.empty()) j["final_state"] = StateJson(scene, result.samples.back());
  j["statistics"] = StatsJson(result.stats);
  j["statistics"]["ligament_kink_crossings"] = result.ligament_kink_crossings;
  j["constraint_residuals"]["max_gap_mm"] = MToMm(result.max_position_residual);
  j["constraint_residuals"]["max_gap_rate_mm_s"] = MToMm(result.max_velocity_residual);
  j["wall_time_s"] = result.wall_time_s;
  // What the run's status would otherwise not say (docs/outputs.md): contacts that pulled,
  // rows whose patella was not followed.
  nlohmann::json listed = nlohmann::json::array();
  for (const OutputWarning& p : warnings) {
    nlohmann::json w = nlohmann::json::object();
    w["kind"] = p.kind;
    if (p.kind == "pulling_contact") {
      w["contact"] = p.contact;
      w["column"] = p.column;
      w["min_force_N"] = p.min_force_N;
    }
    if (p.kind == "short_contact_phase") {
      w["contact"] = p.contact;
      w["duration_s"] = p.duration_s;
    }
    if (p.kind == "liftoff_force_not_zero") {
      w["contact"] = p.contact;
      w["column"] = p.column;
      w["force_N"] = p.force_N;
    }
    if (p.kind == "patella_contact_off") w["contact"] = p.contact;
    if (p.kind == "separated_contact_penetrates" || p.kind == "start_not_at_nearest_points") {
      w["contact"] = p.contact;
      w["column"] = p.column;
    }
    if (p.kind == "ligament_overstretched") {
      w["element"] = p.contact;
      w["column"] = p.column;
    }
    w["time_s"] = p.time_s;
    w["message"] = p.message;
    listed.push_back(std::move(w));
  }
  j["warnings"] = std::move(listed);
  nlohmann::json& versions = j["versions"];
  versions["sundials"] = SUNDIALS_VERSION;
  versions["ceres"] = CERES_VERSION_STRING;
  versions["eigen"] = StrCat(EIGEN_WORLD_VERSION, ".", EIGEN_MAJOR_VERSION, ".", EIGEN_MINOR_VERSION);
  return j;
}

std::vector<OutputWarning> WriteRunOutputs(const std::string& dir_name, const Scene& scene,
                                            const RunSettings& settings, const RunResult& result) {
  CheckOutputDirectory(dir_name);
  const fs::path out = OutputPath(dir_name);
  std::error_code ec;
  if (!out.parent_path().empty()) fs::create_directories(out.parent_path(), ec);
  RemoveStaleTemporaries(out);
  std::random_device random;
  char suffix[64];
  std::snprintf(suffix, sizeof(suffix), "%ld-%08x", static_cast<long>(::getpid()), random());
  const fs::path tmp = out.parent_path() / (TempPrefix(out) + suffix);
  if (!fs::create_directory(tmp, ec) || ec) {
    Throw<InputError>("WriteRunOutputs", "--out = '", EchoPath(dir_name), "': cannot create '",
                      EchoPath(tmp.string()), "' (", ec.message(), ")");
  }
  try {
    const TrajectoryTable table = MakeTrajectoryTable(scene, result);
    std::string csv, sto;  // the header lines
    for (size_t c = 0; c < table.columns.size(); ++c) (csv += c ? "," : "") += table.columns[c];
    csv += '\n';
    sto += StrCat("kneedyn_", scene.name, "\nversion=1\nnRows=", table.rows.size(), "\nnColumns=",
                  table.columns.size(), "\ninDegrees=yes\n",
                  "// lengths in mm, forces in N, angles in deg; formulation ", settings.formulation,
                  result.completed ? "" : "; PARTIAL: solver failed", "\nendheader\n");
    for (size_t c = 0; c < table.columns.size(); ++c) (sto += c ? "\t" : "") += c == 0 ? "time" : table.columns[c];
    sto += '\n';
    // The rows: each number formatted once for both files (empty in the CSV, NaN in the
    // .sto when not finite) and copied at a fixed width into uninitialised buffers sized for
    // the longest rows: no append per number (callgrind, the default chapter_impact run, 62
    // rows of 73 columns: appending cost 0.45 M instructions, a std::string resized to the
    // bound 0.30 M in its zero fill).
    size_t row_bound = 1;
    for (const auto& row : table.rows) row_bound = std::max(row_bound, row.size() * (kTrajectoryNumberChars + 1) + 1);
    const size_t bound = table.rows.size() * row_bound + kTrajectoryNumberChars;
    const std::unique_ptr<char[]> csv_rows(new char[bound]), sto_rows(new char[bound]);
    char* c_out = csv_rows.get();
    char* s_out = sto_rows.get();
    char number[kTrajectoryNumberChars] = {};
    for (const auto& row : table.rows) {
      for (size_t c = 0; c < row.size(); ++c) {
        if (c) {
          *c_out++ = ',';
          *s_out++ = '\t';
        }
        if (std::isfinite(row[c])) {
          const size_t n = FormatTrajectoryNumber(row[c], number);
          std::memcpy(c_out, number, sizeof number);  // the whole width: no call; n count
          std::memcpy(s_out, number, sizeof number);
          c_out += n;
          s_out += n;
        } else {
          std::memcpy(s_out, "NaN", 3);
          s_out += 3;
        }
      }
      *c_out++ = '\n';
      *s_out++ = '\n';
    }
    WriteFile(dir_name, tmp / "trajectory.csv",
              {csv, std::string_view(csv_rows.get(), static_cast<size_t>(c_out - csv_rows.get()))});
    WriteFile(dir_name, tmp / "trajectory.sto",
              {sto, std::string_view(sto_rows.get(), static_cast<size_t>(s_out - sto_rows.get()))});
    // Invalid UTF-8 (e.g. in a file path) is replaced, never thrown on.
    std::vector<OutputWarning> warnings = OutputWarnings(table, result);
    WriteFile(dir_name, tmp / "summary.json",
              {SummaryJson(scene, settings, result, warnings).dump(2, ' ', false, nlohmann::json::error_handler_t::replace),
               "\n"});
    Publish(tmp, out);
    fs::remove_all(tmp, ec);  // the previous set, if there was one
    return warnings;
  } catch (...) {
    fs::remove_all(tmp, ec);
    throw;
  }
}

}  // namespace kneedyn
