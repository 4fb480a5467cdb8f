// Errors at the C++ boundary, built in one place (style.md §4).
// Every message names the function, the offending value and the rule broken.
#pragma once

#include <sstream>
#include <stdexcept>
#include <string>

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

namespace internal {
inline void AppendAll(std::ostringstream&) {}
template <typename Head, typename... Tail>
void AppendAll(std::ostringstream& os, const Head& head, const Tail&... tail) {
  os << head;
  AppendAll(os, tail...);
}
}  // namespace internal

// Concatenates its arguments with full double precision.
template <typename... Args>
std::string StrCat(const Args&... args) {
  std::ostringstream os;
  os.precision(17);
  internal::AppendAll(os, args...);
  return os.str();
}

// A user-given value as shown in a message: at most max_chars characters, non-printable
// bytes (control characters, invalid or non-ASCII UTF-8) as '?', and the full length when
// cut (issue 18: a 100 KB value is not echoed in full).
inline std::string Echo(const std::string& value, size_t max_chars = 80) {
  std::string out;
  for (size_t i = 0; i < value.size() && i < max_chars; ++i) {
    const unsigned char c = static_cast<unsigned char>(value[i]);
    out += (c >= 0x20 && c < 0x7f) ? static_cast<char>(c) : '?';
  }
  if (value.size() > max_chars) out += StrCat("... (", value.size(), " bytes)");
  return out;
}

// "function(): message" as Drake does.
template <typename E = Error, typename... Args>
[[noreturn]] void Throw(const char* function, const Args&... args) {
  throw E(StrCat(function, "(): ", args...));
}

}  // namespace kneedyn
