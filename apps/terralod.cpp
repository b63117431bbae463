// The terralod command-line tool: builds, inspects, extracts and renders terrain levels of detail
// (see 'terralod --help'). Dispatch only: each subcommand lives in apps/cmd_<name>.cpp
// (commands.hpp), parsing and printing only; the work is the library's.
#include <cstdio>
#include <exception>
#include <new>
#include <string>
#include <vector>

#include "cli_common.hpp"
#include "commands.hpp"

#ifndef TERRALOD_VERSION
#define TERRALOD_VERSION "unknown"
#endif

namespace {

using terralod::cli::Args;
using terralod::cli::CommandSpec;
using terralod::cli::UsageError;

struct Command {
  CommandSpec (*spec)();
  int (*run)(const Args&);
};

const std::vector<Command>& commands() {
  static const std::vector<Command> c = {
      {terralod::cli::pm_spec, terralod::cli::cmd_pm},
      {terralod::cli::extract_spec, terralod::cli::cmd_extract},
      {terralod::cli::info_spec, terralod::cli::cmd_info},
      {terralod::cli::demo_spec, terralod::cli::cmd_demo},
      {terralod::cli::generate_spec, terralod::cli::cmd_generate},
      {terralod::cli::view_spec, terralod::cli::cmd_view},
      {terralod::cli::build_spec, terralod::cli::cmd_build},
      {terralod::cli::tin_spec, terralod::cli::cmd_tin},
      {terralod::cli::hybrid_spec, terralod::cli::cmd_hybrid},
      {terralod::cli::texture_spec, terralod::cli::cmd_texture},
      {terralod::cli::fly_spec, terralod::cli::cmd_fly},
      {terralod::cli::export_spec, terralod::cli::cmd_export},
      {terralod::cli::testdem_spec, terralod::cli::cmd_testdem},
      {terralod::cli::objects_spec, terralod::cli::cmd_objects},
#ifdef TERRALOD_HAVE_BENCH  // terralod bench: only when bench/ is built (it adds cmd_bench.cpp)
      {terralod::cli::bench_spec, terralod::cli::cmd_bench},
#endif
  };
  return c;
}

std::string main_usage() {
  std::string u =
      "usage: terralod <command> [options]\n\n"
      "Terrain level of detail with a guaranteed L-infinity error bound.\n\ncommands:\n";
  for (const Command& c : commands()) {
    const CommandSpec s = c.spec();
    u += "  " + s.name + std::string(9 - s.name.size(), ' ') + s.summary + "\n";
  }
  u += "\nRun 'terralod <command> --help' for a command's options.\n"
       "Exit status: 0 success, 1 error (bad data, I/O), 2 bad command line.\n"
       "\noptions:\n  -h, --help  show this help and exit\n  --version   print the version and exit\n";
  return u;
}

}  // namespace

int main(int argc, char** argv) {
  const std::vector<std::string> args(argv + 1, argv + argc);
  if (args.empty()) {
    std::fputs(main_usage().c_str(), stderr);
    return 2;
  }
  if (args[0] == "-h" || args[0] == "--help" || args[0] == "help") {
    std::fputs(main_usage().c_str(), stdout);
    return 0;
  }
  if (args[0] == "--version") {
    std::puts("terralod " TERRALOD_VERSION);
    return 0;
  }
  const Command* cmd = nullptr;
  for (const Command& c : commands())
    if (c.spec().name == args[0]) cmd = &c;
  if (!cmd) {
    std::fprintf(stderr, "terralod: unknown %s '%s' (see 'terralod --help')\n",
                 args[0].rfind("-", 0) == 0 ? "option" : "command", args[0].c_str());
    return 2;
  }
  const CommandSpec spec = cmd->spec();
  try {
    const Args parsed(spec, std::vector<std::string>(args.begin() + 1, args.end()));
    if (parsed.help()) {
      std::fputs(spec.usage().c_str(), stdout);
      return 0;
    }
    return cmd->run(parsed);
  } catch (const UsageError& e) {
    std::fprintf(stderr, "terralod %s: %s (see 'terralod %s --help')\n", spec.name.c_str(), e.what(),
                 spec.name.c_str());
    return 2;
  } catch (const std::bad_alloc&) {
    std::fputs("terralod: out of memory\n", stderr);
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "terralod: %s\n", e.what());
    return 1;
  }
}
