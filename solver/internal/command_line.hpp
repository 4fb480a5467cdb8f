// Command-line parsing shared by kneedyn's programs (every layer's: kneedyn, kneedyn_inverse,
// the benchmarks' and reports' tools): one place that maps CLI11's parse errors to the suite's
// exit codes. --help and --version exit 0; every argument error exits 2 with a message on
// stderr that names the offending argument. Not installed (CLI11 is no dependency of the
// libraries).
#pragma once

#include <CLI/CLI.hpp>

#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

namespace kneedyn {

// Every option of `app` and its subcommands that takes a value refuses an empty one: CLI11
// reads '' as 0 for a number and as "not given" for a text (`--shard ''` ran the whole sweep,
// `--cpu-time ''` recorded 0 s, `score --out ''` wrote beside the result), which a script
// with an unset variable would pass silently.
constexpr const char* kEmptyValue = "the value is empty: give one";
inline void RefuseEmptyValues(CLI::App& app) {
  for (CLI::Option* option : app.get_options()) {
    if (option->get_type_size() == 0) continue;  // a flag
    option->check(CLI::Validator(
        [](std::string& value) { return value.empty() ? std::string(kEmptyValue) : std::string(); },
        ""));
  }
  for (CLI::App* sub : app.get_subcommands([](CLI::App*) { return true; })) RefuseEmptyValues(*sub);
}

// Parses argv into `app`. Returns -1 when the program should go on, else the exit code the
// program must return (0 after --help/--version, 2 after an argument error).
inline int ParseCommandLine(CLI::App& app, int argc, char** argv, const std::string& program) {
  RefuseEmptyValues(app);
  try {
    app.parse(argc, argv);
    return -1;
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == static_cast<int>(CLI::ExitCodes::Success)) return app.exit(e);
    std::string message = e.what();
    // CLI11 prints a validator's refusal as "NAME: TEXT"; the suite's form is "NAME = 'VALUE': rule".
    const std::string empty_suffix = std::string(": ") + kEmptyValue;
    if (message.size() > empty_suffix.size() &&
        message.compare(message.size() - empty_suffix.size(), empty_suffix.size(), empty_suffix) == 0) {
      message = message.substr(0, message.size() - empty_suffix.size()) + " = ''" + empty_suffix;
    }
    // A mistyped subcommand: CLI11 only says that one is required; name the word given.
    const std::vector<CLI::App*> all = app.get_subcommands([](CLI::App*) { return true; });
    if (!all.empty() && app.get_subcommands().empty() && e.get_name() == "RequiredError") {
      std::string expected;
      for (const CLI::App* sub : all) expected += " " + sub->get_name();
      if (argc > 1) {
        const std::string word = argv[1];
        bool known = false;
        for (const CLI::App* sub : all) known = known || sub->check_name(word);
        if (!known && !word.empty() && word[0] == '-') {
          message = "'" + word + "' given before the subcommand; expected one of:" + expected;
        } else if (!known) {
          message = "unknown subcommand '" + word + "'; expected one of:" + expected;
        }
      } else {
        message += "; expected one of:" + expected;
      }
    }
    std::fprintf(stderr, "%s: error: %s\nRun '%s --help' for the arguments.\n", program.c_str(),
                 message.c_str(), program.c_str());
    return 2;
  }
}

}  // namespace kneedyn
