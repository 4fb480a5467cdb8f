// Errors at the C++ boundary, built in one place.
// Every message names the function, the offending value and the rule broken.
#pragma once

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

namespace kneedyn {

class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& what) : std::runtime_error(what) {}
};

// A user input (scene, option, data file) that breaks a rule.
class InputError : public Error {
 public:
  using Error::Error;
};

// A numerical failure (solver return code, singular pose, no convergence).
class SolverError : public Error {
 public:
  using Error::Error;
};

// The shortest decimal that reads back as exactly `v` (std::to_chars' round trip: 1e-6 prints
// as 1e-06, not 9.9999999999999995e-07 as 17 digits do; tests/error_test.cpp), written
// %g-style: fixed for exponents -5 … 16 with every integer digit (100000, not 1e+05), else
// scientific. Non-finite values: inf, -inf, nan.
inline std::string ShortestDouble(double v) {
  if (!std::isfinite(v)) return std::isnan(v) ? "nan" : (v > 0 ? "inf" : "-inf");
  char buf[64];
  const std::to_chars_result r = std::to_chars(buf, buf + sizeof(buf), v, std::chars_format::scientific);
  *r.ptr = '\0';
  // buf = [-]d[.ddd]e±xx: significant digits and the decimal exponent.
  int digits = 0;
  const char* p = buf;
  for (; *p && *p != 'e'; ++p) digits += (*p >= '0' && *p <= '9');
  const int exponent = *p == 'e' ? std::atoi(p + 1) : 0;
  const int precision = (exponent >= -5 && exponent < 17) ? std::max(digits, exponent + 1) : digits;
  std::snprintf(buf, sizeof(buf), "%.*g", precision, v);
  return buf;
}

namespace internal {
inline void AppendAll(std::ostringstream&) {}
template <typename Head, typename... Tail>
void AppendAll(std::ostringstream& os, const Head& head, const Tail&... tail) {
  if constexpr (std::is_floating_point_v<Head>) {
    os << ShortestDouble(static_cast<double>(head));
  } else {
    os << head;
  }
  AppendAll(os, tail...);
}
}  // namespace internal

// Concatenates its arguments; floating-point values as the shortest decimal that reads
// back exactly (ShortestDouble).
template <typename... Args>
std::string StrCat(const Args&... args) {
  std::ostringstream os;
  internal::AppendAll(os, args...);
  return os.str();
}

// A user-given value as shown in a message: at most max_chars characters, non-printable
// bytes (control characters, invalid or non-ASCII UTF-8) as '?', and the full length when
// cut (a 100 KB value is not echoed in full; tests/error_test.cpp).
inline std::string Echo(const std::string& value, size_t max_chars = 80) {
  std::string out;
  for (size_t i = 0; i < value.size() && i < max_chars; ++i) {
    const unsigned char c = static_cast<unsigned char>(value[i]);
    out += (c >= 0x20 && c < 0x7f) ? static_cast<char>(c) : '?';
  }
  if (value.size() > max_chars) out += StrCat("... (", value.size(), " bytes)");
  return out;
}

// A file or directory path as shown in a message: cut at 256 characters rather than 80,
// since real paths (a CI workspace's, a temporary directory's) often pass 80 and the
// reader needs the whole of it to act on the message.
inline std::string EchoPath(const std::string& path) { return Echo(path, 256); }

// Levenshtein distance, for the "nearest valid name" of a refusal message (scene keys,
// sweep and sensitivity names, trajectory columns).
inline int EditDistance(const std::string& a, const std::string& b) {
  std::vector<int> row(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) row[j] = static_cast<int>(j);
  for (size_t i = 1; i <= a.size(); ++i) {
    int diag = row[0];
    row[0] = static_cast<int>(i);
    for (size_t j = 1; j <= b.size(); ++j) {
      const int up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diag + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diag = up;
    }
  }
  return row[b.size()];
}

// "function(): message" as Drake does.
template <typename E = Error, typename... Args>
[[noreturn]] void Throw(const char* function, const Args&... args) {
  throw E(StrCat(function, "(): ", args...));
}

// An error's message printed under `program`'s own name ("kneedyn score: error: …"): a
// leading "program(): ", from a subcommand that threw under that name, is not repeated.
inline std::string MessageUnder(const std::string& program, const std::string& what) {
  const std::string own = program + "(): ";
  return what.compare(0, own.size(), own) == 0 ? what.substr(own.size()) : what;
}

}  // namespace kneedyn
