// Tests of the message helpers (solver/error.hpp): numbers in messages print as the shortest
// decimal that reads back exactly (bounds were printed as 9.9999999999999995e-07).
// Validates: exact round trip (checked with strtod, independently of the formatter) over
// random bit patterns and edge values, the expected spellings of bounds used in messages.
// Echo and EchoPath: values cut at 80 characters, paths at 256, control bytes as '?'.
// Does not validate: locale handling (messages are built in the "C" locale).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <random>

#include "scene/scene.hpp"
#include "solver/error.hpp"

namespace kneedyn {
namespace {

TEST(StrCat, PrintsBoundsAsWritten) {
  EXPECT_EQ(StrCat(1.0e-6), "1e-06");
  EXPECT_EQ(StrCat(0.005), "0.005");
  EXPECT_EQ(StrCat(0.1), "0.1");
  EXPECT_EQ(StrCat(100000.0), "100000");
  EXPECT_EQ(StrCat(1.0e20), "1e+20");
  EXPECT_EQ(StrCat(2.0), "2");
  EXPECT_EQ(StrCat("[", kMinOutputInterval, ", ", 10.0, "] s"), "[1e-06, 10] s");
  EXPECT_EQ(StrCat(1, " of ", 4), "1 of 4");  // integers untouched
}

TEST(StrCat, OutputIntervalMessageHasNoRoundingNoise) {
  std::string why;
  ASSERT_FALSE(IsValidOutputInterval(1.0e-7, 1.0, &why));
  EXPECT_NE(why.find("output interval 1e-07 s; must lie in [1e-06, 10] s"), std::string::npos) << why;
}

// At most 1e5 rows after t = 0: 0.1 s / 1e-6 s is exactly that many, although the quotient
// of the two doubles is 100000.00000000001; one row more is refused.
TEST(OutputInterval, RowLimitCountsRowsNotRoundOff) {
  std::string why;
  EXPECT_TRUE(IsValidOutputInterval(1.0e-6, 0.1, &why)) << why;
  EXPECT_TRUE(IsValidOutputInterval(1.0e-5, 1.0, &why)) << why;
  EXPECT_FALSE(IsValidOutputInterval(1.0e-6, 0.100001, &why));
  EXPECT_NE(why.find("at most 100000 rows"), std::string::npos) << why;
}

TEST(StrCat, NonFiniteValues) {
  EXPECT_EQ(StrCat(std::numeric_limits<double>::infinity()), "inf");
  EXPECT_EQ(StrCat(-std::numeric_limits<double>::infinity()), "-inf");
  EXPECT_EQ(StrCat(std::nan("")), "nan");
}

// Every finite double reads back bitwise, and no shorter %g spelling would.
TEST(StrCat, ShortestRoundTripOverRandomBitPatterns) {
  std::mt19937_64 rng(20261125);
  int checked = 0;
  for (int i = 0; i < 200000; ++i) {
    uint64_t bits = rng();
    double v;
    std::memcpy(&v, &bits, sizeof v);
    if (!std::isfinite(v)) continue;
    const std::string s = ShortestDouble(v);
    const double back = std::strtod(s.c_str(), nullptr);
    ASSERT_EQ(std::memcmp(&back, &v, sizeof v), 0) << s;
    // One significant digit fewer does not round-trip (shortest), unless s is already 1 digit.
    std::string mantissa;
    for (char c : s.substr(0, s.find('e'))) {
      if (c >= '0' && c <= '9') mantissa += c;
    }
    mantissa.erase(0, mantissa.find_first_not_of('0'));
    mantissa.erase(mantissa.find_last_not_of('0') + 1);
    const int digits = static_cast<int>(mantissa.size());
    if (digits > 1 && std::abs(v) >= 1e-5 && std::abs(v) < 1e16) {
      char buf[64];
      std::snprintf(buf, sizeof buf, "%.*e", digits - 2, v);  // digits − 1 significant
      EXPECT_NE(std::strtod(buf, nullptr), v) << s << " vs " << buf;
    }
    ++checked;
  }
  EXPECT_GT(checked, 190000);
  for (double v : {5e-324, 2.2250738585072014e-308, 1.7976931348623157e308, -0.0, 1.0 / 3.0}) {
    EXPECT_EQ(std::strtod(ShortestDouble(v).c_str(), nullptr), v) << ShortestDouble(v);
  }
}

// User values are cut at 80 characters; paths at 256, since a real one (a CI workspace's,
// a temporary directory's) often passes 80 and a cut path cannot be acted on.
TEST(Echo, PathsAreCutAt256CharactersOtherValuesAt80) {
  const std::string path = "/" + std::string(199, 'p');  // 200 characters
  EXPECT_EQ(EchoPath(path), path);
  EXPECT_EQ(Echo(path), path.substr(0, 80) + "... (200 bytes)");
  const std::string long_path = "/" + std::string(299, 'p');
  EXPECT_EQ(EchoPath(long_path), long_path.substr(0, 256) + "... (300 bytes)");
  EXPECT_EQ(EchoPath("/a\x1b[2Jb"), "/a?[2Jb");  // control bytes still shown as '?'
}

}  // namespace
}  // namespace kneedyn
