// Command-line plumbing shared by the terralod tools (see cli_common.hpp).
#include "cli_common.hpp"

#include <unistd.h>

#include <algorithm>
#include <cassert>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <stdexcept>

#include "terralod/pm/atomic_file.hpp"
#include "terralod/pm/json.hpp"

namespace terralod::cli {

// ---------------------------------------------------------------------------------------------
// Usage text

std::string CommandSpec::usage() const {
  // Subcommands print "terralod NAME"; a program of its own (terralod-fly) its own name.
  std::string u = "usage: " + (name.starts_with("terralod") ? name : "terralod " + name);
  bool optional = false;
  for (const OptionSpec& o : options) {
    if (o.required)
      u += " " + o.name + (o.metavar.empty() ? "" : " " + o.metavar);
    else
      optional = true;
  }
  if (optional) u += " [options]";
  if (!positionals.empty()) u += " " + positionals;
  u += "\n\n" + summary + "\n";
  if (!description.empty()) u += "\n" + description + "\n";

  std::vector<std::pair<std::string, std::string>> rows;
  for (const OptionSpec& o : options)
    rows.emplace_back(o.name + (o.metavar.empty() ? "" : " " + o.metavar),
                      o.help + (o.required ? " (required)" : ""));
  rows.emplace_back("-h, --help", "show this help and exit");
  std::size_t width = 0;
  for (const auto& r : rows) width = std::max(width, r.first.size());
  u += "\noptions:\n";
  for (const auto& r : rows)
    u += "  " + r.first + std::string(width + 2 - r.first.size(), ' ') + r.second + "\n";
  return u;
}

std::vector<OptionSpec> concat(std::vector<OptionSpec> a, const std::vector<OptionSpec>& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

// ---------------------------------------------------------------------------------------------
// Argument parsing

namespace {

const OptionSpec* find_option(const CommandSpec& spec, const std::string& name) {
  for (const OptionSpec& o : spec.options)
    if (o.name == name) return &o;
  return nullptr;
}

}  // namespace

Args::Args(const CommandSpec& spec, const std::vector<std::string>& argv) : spec_(&spec) {
  bool options_done = false;
  for (std::size_t i = 0; i < argv.size(); ++i) {
    const std::string& a = argv[i];
    if (options_done || a.size() < 2 || a[0] != '-') {
      positionals_.push_back(a);
      continue;
    }
    if (a == "--") {
      options_done = true;
      continue;
    }
    if (a == "-h" || a == "--help") {
      help_ = true;
      continue;
    }
    const std::size_t eq = a.find('=');
    const std::string name = a.substr(0, eq);
    const OptionSpec* o = a.rfind("--", 0) == 0 ? find_option(spec, name) : nullptr;
    if (!o) throw UsageError("unknown option '" + name + "'");
    if (values_.count(name) && !o->repeatable) throw UsageError("option '" + name + "' given twice");
    if (o->metavar.empty()) {
      if (eq != std::string::npos) throw UsageError("option '" + name + "' takes no value");
      values_[name] = "";
    } else if (eq != std::string::npos) {
      values_[name] = a.substr(eq + 1);
    } else {
      if (i + 1 >= argv.size()) throw UsageError("option '" + name + "' needs a value (" + o->metavar + ")");
      values_[name] = argv[++i];
    }
    all_values_[name].push_back(values_[name]);
  }
  if (help_) return;  // --help wins over everything else
  for (const OptionSpec& o : spec.options)
    if (o.required && !values_.count(o.name))
      throw UsageError("missing option '" + o.name + "'" + (o.metavar.empty() ? "" : " " + o.metavar));
  if (int(positionals_.size()) < spec.min_positionals)
    throw UsageError("missing argument " + spec.positionals);
  if (int(positionals_.size()) > spec.max_positionals)
    throw UsageError("unexpected argument '" + positionals_[spec.max_positionals] + "'");
}

std::vector<std::string> Args::get_all(const std::string& name) const {
  auto it = all_values_.find(name);
  return it == all_values_.end() ? std::vector<std::string>{} : it->second;
}

std::string Args::get(const std::string& name, const std::string& fallback) const {
  auto it = values_.find(name);
  return it == values_.end() ? fallback : it->second;
}

double Args::get_double(const std::string& name, double fallback) const {
  auto it = values_.find(name);
  if (it == values_.end()) return fallback;
  const std::string& s = it->second;
  char* end = nullptr;
  errno = 0;
  const double v = s.empty() ? NAN : std::strtod(s.c_str(), &end);
  if (s.empty() || *end != '\0' || errno == ERANGE || !std::isfinite(v))
    throw UsageError("option '" + name + "' needs a finite number, not '" + s + "'");
  return v;
}

long long Args::get_int(const std::string& name, long long fallback, long long lo, long long hi) const {
  auto it = values_.find(name);
  if (it == values_.end()) return fallback;
  const std::string& s = it->second;
  char* end = nullptr;
  errno = 0;
  const long long v = s.empty() ? 0 : std::strtoll(s.c_str(), &end, 10);
  if (s.empty() || *end != '\0' || errno == ERANGE || v < lo || v > hi)
    throw UsageError("option '" + name + "' needs an integer in [" + std::to_string(lo) + ", " +
                     std::to_string(hi) + "], not '" + s + "'");
  return v;
}

std::pair<long long, long long> Args::get_size(const std::string& name,
                                               std::pair<long long, long long> fallback, long long lo,
                                               long long hi) const {
  auto it = values_.find(name);
  if (it == values_.end()) return fallback;
  const std::string& s = it->second;
  const std::size_t x = s.find_first_of("xX");
  long long v[2] = {0, 0};
  bool ok = x != std::string::npos && x > 0 && x + 1 < s.size();
  for (int k = 0; ok && k < 2; ++k) {
    const std::string part = k == 0 ? s.substr(0, x) : s.substr(x + 1);
    char* end = nullptr;
    errno = 0;
    v[k] = std::strtoll(part.c_str(), &end, 10);
    ok = std::isdigit(static_cast<unsigned char>(part[0])) && *end == '\0' && errno != ERANGE && v[k] >= lo &&
         v[k] <= hi;
  }
  if (!ok)
    throw UsageError("option '" + name + "' needs WxH with W and H integers in [" + std::to_string(lo) +
                     ", " + std::to_string(hi) + "], not '" + s + "'");
  return {v[0], v[1]};
}

std::string Args::get_choice(const std::string& name, const std::vector<std::string>& choices,
                             const std::string& fallback) const {
  auto it = values_.find(name);
  if (it == values_.end()) return fallback;
  if (std::find(choices.begin(), choices.end(), it->second) != choices.end()) return it->second;
  std::string list;
  for (std::size_t i = 0; i < choices.size(); ++i)
    list += (i ? (i + 1 == choices.size() ? " or " : ", ") : "") + choices[i];
  throw UsageError("option '" + name + "' must be " + list + ", not '" + it->second + "'");
}

std::pair<int, int> image_size_option(const Args& a, std::pair<int, int> fallback) {
  auto [width, height] = fallback;
  if (a.has("--size")) {
    const std::string sz = a.get("--size");
    int consumed = 0;
    if (std::sscanf(sz.c_str(), "%dx%d%n", &width, &height, &consumed) != 2 || consumed != int(sz.size()) ||
        width < 1 || height < 1 || width > 16384 || height > 16384)
      throw UsageError("option '--size' needs WxH with each in 1..16384, not '" + sz + "'");
  }
  return {width, height};
}

double tau_option(const Args& a) {
  const double tau = a.get_double("--tau", 1.0);
  if (!(tau > 0)) throw UsageError("option '--tau' must be > 0 pixels, not '" + a.get("--tau") + "'");
  return tau;
}

// ---------------------------------------------------------------------------------------------
// Progress bar

ProgressBar::ProgressBar(std::string label, std::FILE* out)
    : label_(std::move(label)), out_(out), tty_(isatty(fileno(out)) != 0) {}

bool ProgressBar::update(double fraction) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (finished_) return true;
  fraction = std::clamp(std::isfinite(fraction) ? fraction : 0.0, 0.0, 1.0);
  if (tty_) {
    const auto now = std::chrono::steady_clock::now();
    if (drawn_ && fraction < 1.0 && now - last_draw_ < std::chrono::milliseconds(100)) return true;
    last_draw_ = now;
    draw(fraction);
  } else {
    const int decile = int(fraction * 10.0 + 1e-9);
    if (decile > last_decile_) {
      last_decile_ = decile;
      std::fprintf(out_, "%s: %d%%\n", label_.c_str(), decile * 10);
      std::fflush(out_);
    }
  }
  return true;
}

void ProgressBar::draw(double fraction) {
  constexpr int kWidth = 40;
  const int filled = int(fraction * kWidth);
  std::string bar(std::size_t(filled), '#');
  bar += std::string(std::size_t(kWidth - filled), '.');
  std::fprintf(out_, "\r%s [%s] %5.1f%%", label_.c_str(), bar.c_str(), fraction * 100.0);
  std::fflush(out_);
  drawn_ = true;
}

void ProgressBar::finish() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (finished_) return;
  finished_ = true;
  if (tty_ && drawn_) {
    // Blank the line so that the stage lines that follow start clean.
    std::fprintf(out_, "\r%s\r", std::string(label_.size() + 52, ' ').c_str());
    std::fflush(out_);
  }
}

// ---------------------------------------------------------------------------------------------
// Output

void print_line(const std::string& s) {
  std::fputs((s + "\n").c_str(), stdout);
  std::fflush(stdout);
}

void check_output_folder(const std::string& path) {
  const std::filesystem::path parent = std::filesystem::path(path).parent_path();
  std::error_code ec;
  if (!parent.empty() && !std::filesystem::is_directory(parent, ec))
    throw std::runtime_error(path + ": cannot write, folder '" + parent.string() + "' does not exist");
}

// ---------------------------------------------------------------------------------------------
// Formatting

std::string format_duration(double ms) {
  if (ms < 1000.0) return strf("%.0f ms", ms);
  return strf("%.1f s", ms / 1000.0);
}

std::string format_bytes(std::uint64_t bytes) {
  if (bytes < 1000) return strf("%llu bytes", static_cast<unsigned long long>(bytes));
  if (bytes < 1000000) return strf("%.1f kB", double(bytes) / 1e3);
  if (bytes < 1000000000) return strf("%.1f MB", double(bytes) / 1e6);
  return strf("%.2f GB", double(bytes) / 1e9);
}

void write_text_file(const std::string& path, const std::string& text) {
  pm::write_file_atomically(path, text);
}

void write_statistics(const std::string& path, const JsonWriter& j) {
  write_text_file(path, j.str());
  print_line(strf("write %s: statistics", path.c_str()));
}

std::string strf(const char* fmt, ...) {
  va_list ap;
  va_start(ap, fmt);
  va_list ap2;
  va_copy(ap2, ap);
  const int n = std::vsnprintf(nullptr, 0, fmt, ap);
  va_end(ap);
  std::string s(n > 0 ? std::size_t(n) : 0, '\0');
  if (n > 0) std::vsnprintf(s.data(), s.size() + 1, fmt, ap2);
  va_end(ap2);
  return s;
}

// ---------------------------------------------------------------------------------------------
// JSON

std::string JsonWriter::number(double v) {
  if (!std::isfinite(v)) return "null";
  if (v == 0.0) return "0";  // also turns -0 into 0
  return strf("%.17g", v);
}

void JsonWriter::prefix(const std::string& key) {
  if (!open_.empty()) {
    assert(open_.back().array == key.empty() && "keys inside objects, none inside arrays");
    out_ += open_.back().empty ? "\n" : ",\n";
    open_.back().empty = false;
    out_.append(2 * open_.size(), ' ');
  }
  if (!key.empty()) out_ += pm::json_quote(key) + ": ";
}

void JsonWriter::close([[maybe_unused]] bool array, char bracket) {
  assert(!open_.empty() && open_.back().array == array && "end_* matches its begin_*");
  const bool empty = open_.back().empty;
  open_.pop_back();
  if (!empty) {
    out_ += '\n';
    out_.append(2 * open_.size(), ' ');
  }
  out_ += bracket;
  if (open_.empty()) out_ += "\n";
}

void JsonWriter::begin_object(const std::string& key) {
  prefix(key);
  out_ += "{";
  open_.push_back({/*array=*/false});
}

void JsonWriter::end_object() { close(/*array=*/false, '}'); }

void JsonWriter::begin_array(const std::string& key) {
  prefix(key);
  out_ += "[";
  open_.push_back({/*array=*/true});
}

void JsonWriter::end_array() { close(/*array=*/true, ']'); }

void JsonWriter::field(const std::string& key, const std::string& value) {
  prefix(key);
  out_ += pm::json_quote(value);
}

void JsonWriter::field(const std::string& key, double value) {
  prefix(key);
  out_ += number(value);
}

void JsonWriter::field(const std::string& key, std::uint64_t value) {
  prefix(key);
  out_ += std::to_string(value);
}

void JsonWriter::field(const std::string& key, bool value) {
  prefix(key);
  out_ += value ? "true" : "false";
}

}  // namespace terralod::cli
