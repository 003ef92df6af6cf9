#include "tools/common/command_line.hpp"

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>

namespace epitrack::tools {

CommandLine::CommandLine(std::string program, std::string synopsis, std::string description)
    : program_(std::move(program)),
      synopsis_(std::move(synopsis)),
      description_(std::move(description)) {}

void CommandLine::option(const std::string& name, const std::string& metavar,
                         const std::string& help,
                         std::function<bool(const std::string&, std::string&)> apply) {
  options_.push_back({name, metavar, help, std::move(apply), {}, false, false});
}

void CommandLine::flag(const std::string& name, const std::string& help, bool* target) {
  option(name, "", help, [target](const std::string&, std::string&) {
    *target = true;
    return true;
  });
}

void CommandLine::text(const std::string& name, const std::string& metavar, const std::string& help,
                       std::string* target) {
  option(name, metavar, help, [target](const std::string& v, std::string& err) {
    if (v.empty()) {
      err = "expected a non-empty value";
      return false;
    }
    *target = v;
    return true;
  });
}

void CommandLine::integer(const std::string& name, const std::string& metavar,
                          const std::string& help, int* target, long lo, long hi) {
  option(name, metavar, help, [target, lo, hi](const std::string& v, std::string& err) {
    errno = 0;
    char* end = nullptr;
    const long x = std::strtol(v.c_str(), &end, 10);
    if (v.empty() || *end != '\0' || errno != 0 || x < lo || x > hi) {
      err = "expected an integer in " + std::to_string(lo) + ".." + std::to_string(hi) + ", got '" +
            v + "'";
      return false;
    }
    *target = static_cast<int>(x);
    return true;
  });
  std::ostringstream range;  // (a stream: GCC 12's -Wrestrict misfires on the string sum)
  range << "[" << lo << ".." << hi << "]";
  options_.back().range = range.str();
}

void CommandLine::real(const std::string& name, const std::string& metavar, const std::string& help,
                       double* target, double lo, double hi) {
  option(name, metavar, help, [target, lo, hi](const std::string& v, std::string& err) {
    errno = 0;
    char* end = nullptr;
    const double x = std::strtod(v.c_str(), &end);
    if (v.empty() || *end != '\0' || errno != 0 || !std::isfinite(x) || x < lo || x > hi) {
      std::ostringstream s;
      s << "expected a number in " << lo << ".." << hi << ", got '" << v << "'";
      err = s.str();
      return false;
    }
    *target = x;
    return true;
  });
  std::ostringstream range;
  range << "[" << lo << ".." << hi << "]";
  options_.back().range = range.str();
}

void CommandLine::choice(const std::string& name, const std::vector<std::string>& choices,
                         const std::string& help, std::string* target) {
  std::string meta;
  for (const auto& c : choices) meta += (meta.empty() ? "" : "|") + c;
  option(name, meta, help, [target, choices, meta](const std::string& v, std::string& err) {
    for (const auto& c : choices) {
      if (v == c) {
        *target = v;
        return true;
      }
    }
    err = "expected one of " + meta + ", got '" + v + "'";
    return false;
  });
}

void CommandLine::positional(const std::string& name, const std::string& help, std::string* target,
                             bool required) {
  positionals_.push_back({name, help, target, required});
}

void CommandLine::require(const std::string& name) {
  if (Option* o = find(name)) o->required = true;
}

CommandLine::Option* CommandLine::find(const std::string& name) {
  for (auto& o : options_) {
    if (o.name == name) return &o;
  }
  return nullptr;
}

bool CommandLine::given(const std::string& name) const {
  for (const auto& o : options_) {
    if (o.name == name) return o.seen;
  }
  return false;
}

std::string CommandLine::helpText() const {
  std::ostringstream s;
  s << "usage: " << program_ << " " << synopsis_ << "\n\n" << description_ << "\n";
  if (!positionals_.empty()) {
    s << "\narguments:\n";
    for (const auto& p : positionals_) s << "  " << p.name << "\n      " << p.help << "\n";
  }
  s << "\noptions:\n";
  for (const auto& o : options_) {
    s << "  --" << o.name << (o.metavar.empty() ? "" : " " + o.metavar)
      << (o.range.empty() ? "" : "  " + o.range) << (o.required ? "  (required)" : "") << "\n      "
      << o.help << "\n";
  }
  s << "  --help\n      print this help and exit\n";
  return s.str();
}

std::vector<std::string> CommandLine::optionNames() const {
  std::vector<std::string> names;
  names.reserve(options_.size());
  for (const auto& o : options_) names.push_back(o.name);
  return names;
}

int CommandLine::usageError(const std::string& message) const {
  std::fprintf(stderr, "%s: %s (see --help)\n", program_.c_str(), message.c_str());
  return 2;
}

CommandLine::Result CommandLine::parse(int argc, const char* const* argv) {
  std::size_t next_positional = 0;
  bool only_positionals = false;
  for (int i = 1; i < argc; ++i) {
    std::string arg = argv[i];
    if (!only_positionals && arg == "--") {
      only_positionals = true;
      continue;
    }
    if (!only_positionals && (arg == "--help" || arg == "-h")) {
      std::fputs(helpText().c_str(), stdout);
      return Result::kHelp;
    }
    if (!only_positionals && arg.size() > 2 && arg.compare(0, 2, "--") == 0) {
      std::string name = arg.substr(2);
      std::string value;
      bool has_value = false;
      if (const auto eq = name.find('='); eq != std::string::npos) {
        value = name.substr(eq + 1);
        name = name.substr(0, eq);
        has_value = true;
      }
      Option* o = find(name);
      if (o == nullptr) {
        usageError("unknown option '--" + name + "'");
        return Result::kError;
      }
      if (o->metavar.empty()) {
        if (has_value) {
          usageError("option '--" + name + "' takes no value");
          return Result::kError;
        }
      } else if (!has_value) {
        if (i + 1 >= argc) {
          usageError("option '--" + name + "' needs a value " + o->metavar);
          return Result::kError;
        }
        value = argv[++i];
      }
      std::string err;
      if (!o->apply(value, err)) {
        usageError("--" + name + ": " + err);
        return Result::kError;
      }
      o->seen = true;
      continue;
    }
    if (next_positional >= positionals_.size()) {
      usageError("unexpected argument '" + arg + "'");
      return Result::kError;
    }
    *positionals_[next_positional++].target = arg;
  }
  for (std::size_t p = next_positional; p < positionals_.size(); ++p) {
    if (positionals_[p].required) {
      usageError("missing argument " + positionals_[p].name);
      return Result::kError;
    }
  }
  for (const auto& o : options_) {
    if (o.required && !o.seen) {
      usageError("missing required option --" + o.name);
      return Result::kError;
    }
  }
  return Result::kOk;
}

bool parseSize(const std::string& text, int& width, int& height) {
  const auto x = text.find('x');
  if (x == std::string::npos) return false;
  char* end = nullptr;
  const long w = std::strtol(text.c_str(), &end, 10);
  if (end != text.c_str() + x) return false;
  const long h = std::strtol(text.c_str() + x + 1, &end, 10);
  if (*end != '\0' || w <= 0 || h <= 0 || w > 16384 || h > 16384) return false;
  width = static_cast<int>(w);
  height = static_cast<int>(h);
  return true;
}

bool parseDoubleList(const std::string& text, std::vector<double>& values) {
  values.clear();
  std::size_t start = 0;
  while (start <= text.size()) {
    const auto comma = text.find(',', start);
    const std::string part =
        text.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    char* end = nullptr;
    const double v = std::strtod(part.c_str(), &end);
    if (part.empty() || *end != '\0' || !std::isfinite(v)) return false;
    values.push_back(v);
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  return !values.empty();
}

}  // namespace epitrack::tools
