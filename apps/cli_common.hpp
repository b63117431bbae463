// Command-line plumbing shared by the terralod tools: option parsing, usage text, progress
// bar, stage lines, human-readable sizes and times, and a tiny JSON writer. No terrain
// algorithm lives here.
#pragma once

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <map>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "terralod/pm/timing.hpp"

namespace terralod::cli {

/// A bad command line (unknown option, missing or malformed value): exit code 2.
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// One option of a subcommand. `metavar` empty = a flag without a value.
struct OptionSpec {
  std::string name;     ///< with the leading dashes, e.g. "--out"
  std::string metavar;  ///< e.g. "FILE"; empty for flags
  std::string help;     ///< one line
  bool required = false;
  bool repeatable = false;  ///< may be given several times (Args::get_all); get() returns the last
};

/// A subcommand's interface: what `--help` prints and what the parser accepts.
struct CommandSpec {
  std::string name;         ///< e.g. "pm"
  std::string positionals;  ///< e.g. "FILE" (shown in the usage line); empty = none accepted
  int min_positionals = 0, max_positionals = 0;
  std::string summary;      ///< one line, also shown by `terralod --help`
  std::string description;  ///< a paragraph or two after the usage line
  std::vector<OptionSpec> options;

  /// The full text of `terralod <name> --help`.
  std::string usage() const;
};

/// `a` followed by `b` (option groups shared by several commands, in --help order).
std::vector<OptionSpec> concat(std::vector<OptionSpec> a, const std::vector<OptionSpec>& b);

/// Parsed arguments of one subcommand. `--name value` and `--name=value` are accepted; `--`
/// ends the options; `-h`/`--help` sets help. Throws UsageError naming the offending option.
class Args {
 public:
  Args(const CommandSpec& spec, const std::vector<std::string>& argv);

  bool help() const { return help_; }
  bool has(const std::string& name) const { return values_.count(name) != 0; }
  /// The option's value, or `fallback` when it was not given.
  std::string get(const std::string& name, const std::string& fallback = {}) const;
  /// A finite number (UsageError naming the option otherwise), or `fallback`.
  double get_double(const std::string& name, double fallback) const;
  /// An integer in [lo, hi] (UsageError naming the option otherwise), or `fallback`.
  long long get_int(const std::string& name, long long fallback, long long lo, long long hi) const;
  /// "WxH" with W and H integers in [lo, hi] (UsageError naming the option otherwise), or
  /// `fallback`.
  std::pair<long long, long long> get_size(const std::string& name, std::pair<long long, long long> fallback,
                                           long long lo, long long hi) const;
  /// One of `choices` (UsageError listing them otherwise), or `fallback`.
  std::string get_choice(const std::string& name, const std::vector<std::string>& choices,
                         const std::string& fallback) const;
  /// Every value of a repeatable option, in command-line order (empty when not given).
  std::vector<std::string> get_all(const std::string& name) const;
  const std::vector<std::string>& positionals() const { return positionals_; }

 private:
  const CommandSpec* spec_;
  bool help_ = false;
  std::map<std::string, std::string> values_;
  std::map<std::string, std::vector<std::string>> all_values_;  ///< every value, repeatable or not
  std::vector<std::string> positionals_;
};

/// --size WxH of an image or viewport, W and H in 1..16384 (UsageError "option '--size' needs WxH
/// with each in 1..16384, not '...'" otherwise), or `fallback` when not given.
std::pair<int, int> image_size_option(const Args& a, std::pair<int, int> fallback);
/// --tau PIXELS, the screen-space error tolerance: > 0 (UsageError naming the value otherwise),
/// default 1.
double tau_option(const Args& a);

/// Progress bar for BuildOptions::progress: on a TTY redraws one line with '\r' at most ten
/// times a second; otherwise prints "label: 10%" lines every 10 %. Thread-safe.
class ProgressBar {
 public:
  ProgressBar(std::string label, std::FILE* out = stderr);
  ~ProgressBar() { finish(); }
  /// Reports a fraction in [0, 1]; always returns true (never cancels).
  bool update(double fraction);
  /// Clears the bar (TTY) so that the next line starts clean. Idempotent.
  void finish();

 private:
  void draw(double fraction);
  std::string label_;
  std::FILE* out_;
  bool tty_;
  bool finished_ = false;
  int last_decile_ = -1;
  std::chrono::steady_clock::time_point last_draw_{};
  bool drawn_ = false;
  std::mutex mutex_;
};

/// Prints one stage line: `s` and a newline to stdout, flushed at once (it shows before the
/// next, possibly long, stage starts).
void print_line(const std::string& s);

/// Fails early (before a long build) when the folder of the output `path` does not exist:
/// std::runtime_error "<path>: cannot write, folder '<folder>' does not exist".
void check_output_folder(const std::string& path);

/// Writes `text` to path + ".tmp", then renames it onto path (never half-written);
/// std::runtime_error "<path>: cannot write ..." on failure.
void write_text_file(const std::string& path, const std::string& text);

class JsonWriter;
/// Writes the JSON of --stats to `path` (write_text_file) and prints "write PATH: statistics".
void write_statistics(const std::string& path, const JsonWriter& j);

/// Milliseconds since `start` (terralod/pm/timing.hpp).
using terralod::pm::ms_since;
/// "12 ms" below a second, "16.9 s" above.
std::string format_duration(double ms);
/// "512 bytes", "12.3 kB", "7.1 MB", "1.2 GB" (powers of 1000).
std::string format_bytes(std::uint64_t bytes);
/// printf-style formatting into a std::string.
std::string strf(const char* fmt, ...) __attribute__((format(printf, 1, 2)));

/// Minimal pretty-printing JSON writer: objects, arrays, strings (terralod/pm/json.hpp's
/// json_quote), numbers (%.17g; null if not finite), integers, booleans. Keys and values are
/// emitted in call order. Inside an object every member has a non-empty key (field,
/// begin_object(key), begin_array(key)); inside an array the items have none (begin_object(),
/// begin_array()); each begin_* is closed by its end_* (asserted).
class JsonWriter {
 public:
  void begin_object(const std::string& key = {});
  void end_object();
  void begin_array(const std::string& key = {});
  void end_array();
  void field(const std::string& key, const std::string& value);
  void field(const std::string& key, const char* value) { field(key, std::string(value)); }
  void field(const std::string& key, double value);
  void field(const std::string& key, std::uint64_t value);
  void field(const std::string& key, int value) { field(key, static_cast<std::uint64_t>(value)); }
  void field(const std::string& key, bool value);
  const std::string& str() const { return out_; }

  /// %.17g, or null when not finite.
  static std::string number(double v);

 private:
  struct Open {
    bool array;         // an array (items without keys), else an object
    bool empty = true;  // nothing written in it yet
  };
  void prefix(const std::string& key);
  void close(bool array, char bracket);
  std::string out_;
  std::vector<Open> open_;
};

}  // namespace terralod::cli
