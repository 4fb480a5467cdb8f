// Command-line parsing shared by kneedyn's tools: one place that
// maps CLI11's parse errors to the suite's exit codes. --help and --version exit 0; every
// argument error exits 2 with a message on stderr that names the offending argument.
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

// Parses argv into `app`. Returns -1 when the program should go on, else the exit code the
// program must return (0 after --help/--version, 2 after an argument error).
inline int ParseCommandLine(CLI::App& app, int argc, char** argv, const std::string& program) {
  try {
    app.parse(argc, argv);
    return -1;
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == static_cast<int>(CLI::ExitCodes::Success)) return app.exit(e);
    std::string message = e.what();
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
