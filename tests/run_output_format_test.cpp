// The numbers of trajectory.csv and trajectory.sto are formatted by std::to_chars
// (FormatTrajectoryNumber) instead of snprintf("%.12g"). The files must stay byte-identical:
//  - the formatter agrees with snprintf("%.12g") on special values, decade and rounding
//    boundaries and 600,000 doubles of every magnitude (random bit patterns, and values of
//    the ranges the columns hold), and on 12-digit midpoints, their neighbours and carries;
//  - the files WriteRunOutputs writes equal those of the snprintf writer they replaced, kept
//    below verbatim as the oracle (formulations/run_output.cpp of 68610df), on several scenes
//    and formulations, with separated contacts (empty CSV cells, NaN in the .sto) and a
//    partial run (the PARTIAL header line).
#include <gtest/gtest.h>

#include <cfloat>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <random>
#include <sstream>

#include "formulations/run.hpp"
#include "formulations/run_output.hpp"
#include "scene/scene.hpp"
#include "tests/cli_support.hpp"
#include "tests/test_support.hpp"

using namespace kneedyn;
using kneedyn::cli_test::ReadText;
using kneedyn::test_support::ScenesDir;
namespace fs = std::filesystem;

namespace {

std::string Printf12g(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.12g", v);
  return buf;
}

std::string ToChars12g(double v) {
  char buf[kTrajectoryNumberChars];
  return std::string(buf, FormatTrajectoryNumber(v, buf));
}

// The snprintf writer (run_output.cpp at 68610df), verbatim but for returning strings.
std::string OracleFormatDouble(double v) {
  if (!std::isfinite(v)) return "";
  char buf[40];
  std::snprintf(buf, sizeof(buf), "%.12g", v);
  return buf;
}
void OracleFiles(const Scene& scene, const RunSettings& settings, const RunResult& result, std::string* csv_text,
                 std::string* sto_text) {
  const TrajectoryTable table = MakeTrajectoryTable(scene, result);
  std::ostringstream csv, sto;
  for (size_t c = 0; c < table.columns.size(); ++c) csv << (c ? "," : "") << table.columns[c];
  csv << "\n";
  sto << "kneedyn_" << scene.name << "\nversion=1\nnRows=" << table.rows.size()
      << "\nnColumns=" << table.columns.size() << "\ninDegrees=yes\n"
      << "// lengths in mm, forces in N, angles in deg; formulation " << settings.formulation
      << (result.completed ? "" : "; PARTIAL: solver failed") << "\nendheader\n";
  for (size_t c = 0; c < table.columns.size(); ++c) {
    sto << (c ? "\t" : "") << (c == 0 ? std::string("time") : table.columns[c]);
  }
  sto << "\n";
  for (const auto& row : table.rows) {
    for (size_t c = 0; c < row.size(); ++c) {
      csv << (c ? "," : "") << OracleFormatDouble(row[c]);
      sto << (c ? "\t" : "") << (std::isfinite(row[c]) ? OracleFormatDouble(row[c]) : "NaN");
    }
    csv << "\n";
    sto << "\n";
  }
  *csv_text = csv.str();
  *sto_text = sto.str();
}

}  // namespace

TEST(TrajectoryNumber, SpecialAndBoundaryValuesAsPrintf) {
  std::vector<double> values = {0.0, -0.0, 1.0, -1.0, 0.1, 0.5, 1.5, 2.5, 1e-5, 1e-4, 9.99999999999e-5,
                                9.999999999995e-5, 0.0001, 0.00012345678901234, 123456789012.0,
                                999999999999.0, 999999999999.5, 1e12, 1e15, 1e16, 1e17, 1e22, 1e100,
                                DBL_MAX, -DBL_MAX, DBL_MIN, -DBL_MIN, DBL_TRUE_MIN, 4.9406564584124654e-324,
                                2.2250738585072009e-308, 1.0 / 3.0, 2.0 / 3.0, M_PI, 1e-300, 123.456,
                                0.30000000000000004, 5e-324, 1.00000000000050, 1.0000000000005,
                                0.15000000000000002, 6.02214076e23, 90.0, -90.0, 180.0};
  for (int e = -320; e <= 308; ++e) {
    const double p = std::pow(10.0, e);
    for (double v : {p, std::nextafter(p, 0.0), std::nextafter(p, INFINITY), 5.0 * p, 9.9999999999950 * p,
                     9.9999999999949 * p, 1.2345678901245 * p}) {
      values.push_back(v);
      values.push_back(-v);
    }
  }
  for (double v : values) {
    if (!std::isfinite(v)) continue;
    EXPECT_EQ(ToChars12g(v), Printf12g(v)) << "bits of v: " << std::hexfloat << v;
  }
}

TEST(TrajectoryNumber, RandomDoublesOfEveryMagnitudeAsPrintf) {
  std::mt19937_64 rng(20261125);
  long mismatches = 0;
  for (int i = 0; i < 400000; ++i) {
    const uint64_t bits = rng();
    double v;
    std::memcpy(&v, &bits, sizeof v);
    if (!std::isfinite(v)) continue;
    if (ToChars12g(v) != Printf12g(v) && ++mismatches <= 5) {
      ADD_FAILURE() << std::hexfloat << v << ": to_chars " << ToChars12g(v) << ", printf " << Printf12g(v);
    }
  }
  // The columns' own ranges: angles, mm, N, strains, times; values with few digits.
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::uniform_int_distribution<int> decade(-12, 6);
  for (int i = 0; i < 200000; ++i) {
    double v = unit(rng) * std::pow(10.0, decade(rng));
    if (i % 4 == 0) v = std::round(v * 1e6) / 1e6;  // short decimals: ties and trailing zeros
    if (ToChars12g(v) != Printf12g(v) && ++mismatches <= 5) {
      ADD_FAILURE() << std::hexfloat << v << ": to_chars " << ToChars12g(v) << ", printf " << Printf12g(v);
    }
  }
  EXPECT_EQ(mismatches, 0);
}

// Near the formatter's rounding decisions: doubles nearest the 12-digit midpoints (13
// digits ending in 5), their neighbours one ulp away, exact dyadic ties, and 12-digit values
// with runs of 9 (the carry into a new leading digit) of every decade, against printf.
TEST(TrajectoryNumber, TwelveDigitMidpointsAndCarriesAsPrintf) {
  std::mt19937_64 rng(20261202);
  std::uniform_int_distribution<long long> mantissa(100000000000LL, 999999999999LL);
  std::uniform_int_distribution<int> decade(-20, 20);
  long mismatches = 0;
  auto check = [&](double v) {
    for (double w : {v, -v, std::nextafter(v, 0.0), std::nextafter(v, INFINITY)}) {
      if (ToChars12g(w) != Printf12g(w) && ++mismatches <= 5) {
        ADD_FAILURE() << std::hexfloat << w << ": formatter " << ToChars12g(w) << ", printf " << Printf12g(w);
      }
    }
  };
  // Exact ties at the 13th digit (dyadic values; printf rounds them to even).
  for (double v : {1234567890.125, 100000000000.5, 100000000001.5, 0.000152587890625, 2.384185791015625e-07,
                   1.1920928955078125e-07, 3.0517578125e-05, 9.5367431640625e-07}) {
    check(v);
  }
  char text[64];
  for (int i = 0; i < 100000; ++i) {
    std::snprintf(text, sizeof text, "%lld5e%d", mantissa(rng), decade(rng));  // 13 digits, last 5
    check(std::strtod(text, nullptr));
    std::snprintf(text, sizeof text, "%lld9999e%d", mantissa(rng) / 1000 * 1000 + 999, decade(rng));
    check(std::strtod(text, nullptr));
  }
  EXPECT_EQ(mismatches, 0);
}

TEST(TrajectoryFiles, ByteIdenticalToTheSnprintfWriter) {
  struct Case {
    const char* scene;  // under reference-data/scenes/
    const char* formulation;
    long max_steps;  // > 0: a budget that stops the run (partial)
  };
  const Case cases[] = {
      {"chapter_impact.yaml", "dae", 0},
      {"chapter_impact.yaml", "ede", 0},
      {"hard/lateral_pulse_recontact.yaml", "dae-reduced", 0},  // separations
      {"no_contact.yaml", "mde", 0},
      {"one_ligament.yaml", "newmark", 0},
      {"chapter_impact.yaml", "dae", 10},  // partial (its first row)
  };
  const fs::path work = fs::temp_directory_path() / "kneedyn_run_output_format_test";
  fs::remove_all(work);
  fs::create_directories(work);
  int with_empty_cells = 0, partial = 0, index = 0;
  for (const Case& c : cases) {
    SCOPED_TRACE(std::string(c.scene) + " with " + c.formulation);
    const Scene scene = LoadScene(ScenesDir() + "/" + c.scene);
    RunSettings settings;
    settings.formulation = c.formulation;
    settings.options.rtol = 1e-6;
    settings.options.atol = 1e-8;
    if (c.max_steps > 0) settings.options.max_steps = c.max_steps;
    const RunResult result = RunScene(scene, settings);
    EXPECT_EQ(result.completed, c.max_steps == 0) << result.failure;
    partial += !result.completed;
    const fs::path out = work / std::to_string(index++);
    WriteRunOutputs(out.string(), scene, settings, result);
    std::string csv, sto;
    OracleFiles(scene, settings, result, &csv, &sto);
    EXPECT_GE(result.samples.size(), c.max_steps > 0 ? 1u : 3u);
    EXPECT_EQ(ReadText(out / "trajectory.csv"), csv);
    EXPECT_EQ(ReadText(out / "trajectory.sto"), sto);
    with_empty_cells += csv.find(",,") != std::string::npos && sto.find("\tNaN") != std::string::npos;
  }
  // The cases cover what they claim: cells of separated contacts and a partial run.
  EXPECT_GE(with_empty_cells, 1);
  EXPECT_EQ(partial, 1);
  fs::remove_all(work);
}

// The fast path's every layout (1.58e-30 ≤ |v| < 1e12: d.ddde-XX for X ≤ −5, 0.000ddd for
// −4 ≤ X < 0, fixed for 0 ≤ X < 12), its decimal-exponent correction (values one ulp either
// side of each power of ten) and its trailing-zero trim (integers and short decimals), decade
// by decade, against printf, and the exact path on either side of it. Fails if a branch drops
// a digit, misplaces the point or rounds; under UBSan (bash .ci/bootstrap sanitize), if the
// scaling reads past its table of powers of ten.
TEST(TrajectoryNumber, EveryDecadeOfTheFastPathAsPrintf) {
  std::mt19937_64 rng(20261203);
  std::uniform_real_distribution<double> unit(1.0, 10.0);
  long mismatches = 0, checked = 0;
  auto check = [&](double v) {
    for (double w : {v, -v}) {
      ++checked;
      if (ToChars12g(w) != Printf12g(w) && ++mismatches <= 5) {
        ADD_FAILURE() << std::hexfloat << w << ": formatter " << ToChars12g(w) << ", printf " << Printf12g(w);
      }
    }
  };
  for (int x = -32; x <= 12; ++x) {
    const double p = std::pow(10.0, x);
    for (double v : {p, std::nextafter(p, 0.0), std::nextafter(p, INFINITY)}) check(v);
    for (int i = 0; i < 5000; ++i) {
      const double m = unit(rng);
      check(m * p);
      check(std::round(m * 1e3) / 1e3 * p);  // 4 significant digits: trimmed zeros
      check(std::round(m) * p);              // one digit
    }
  }
  for (long k = 1; k < 2000000; k += 997) check(static_cast<double>(k));  // integers: no point
  EXPECT_EQ(mismatches, 0);
  EXPECT_GT(checked, 600000);
}
