#pragma once

#include <functional>
#include <string>
#include <vector>

namespace epitrack::tools {

/// A small command-line parser shared by every command: `--name VALUE` or `--name=VALUE` options,
/// flags, positionals, typed range checks and `--help`. Unknown options, missing values,
/// out-of-range numbers and missing required arguments end the program with one line naming the
/// problem and exit code 2 (ARCHITECTURE.md: "exit ... 2 bad usage").
class CommandLine {
 public:
  enum class Result { kOk, kHelp, kError };

  CommandLine(std::string program, std::string synopsis, std::string description);

  /// A generic option; `apply` validates and stores the value, filling `error` when it fails.
  void option(const std::string& name, const std::string& metavar, const std::string& help,
              std::function<bool(const std::string& value, std::string& error)> apply);
  /// Integer and real options check `lo <= value <= hi`; --help prints the range as `[lo..hi]`
  /// after the option's name (the command-line test reads it to try values outside).
  void flag(const std::string& name, const std::string& help, bool* target);
  void text(const std::string& name, const std::string& metavar, const std::string& help,
            std::string* target);
  void integer(const std::string& name, const std::string& metavar, const std::string& help,
               int* target, long lo, long hi);
  void real(const std::string& name, const std::string& metavar, const std::string& help,
            double* target, double lo, double hi);
  /// One of the listed words.
  void choice(const std::string& name, const std::vector<std::string>& choices,
              const std::string& help, std::string* target);
  void positional(const std::string& name, const std::string& help, std::string* target,
                  bool required = true);
  /// Marks an option as required.
  void require(const std::string& name);

  /// Parses; prints help (kHelp) or one error line (kError) to stderr.
  Result parse(int argc, const char* const* argv);
  /// Exit code for a result that is not kOk: 0 for help, 2 for errors.
  static int exitCode(Result r) { return r == Result::kHelp ? 0 : 2; }

  [[nodiscard]] bool given(const std::string& name) const;
  [[nodiscard]] std::string helpText() const;
  /// Prints "program: message" to stderr and returns 2 (for checks after parsing).
  int usageError(const std::string& message) const;
  [[nodiscard]] const std::string& program() const { return program_; }
  /// Names of every registered option (without the leading --), in registration order.
  [[nodiscard]] std::vector<std::string> optionNames() const;

 private:
  struct Option {
    std::string name;
    std::string metavar;  // empty for flags
    std::string help;
    std::function<bool(const std::string&, std::string&)> apply;
    std::string range;  // "[lo..hi]" for numbers, empty otherwise
    bool required = false;
    bool seen = false;
  };
  struct Positional {
    std::string name;
    std::string help;
    std::string* target;
    bool required;
  };
  Option* find(const std::string& name);

  std::string program_;
  std::string synopsis_;
  std::string description_;
  std::vector<Option> options_;
  std::vector<Positional> positionals_;
};

/// Parses "WxH" (e.g. 704x576) into positive integers.
bool parseSize(const std::string& text, int& width, int& height);
/// Parses a comma-separated list of doubles ("0.1,-0.02").
bool parseDoubleList(const std::string& text, std::vector<double>& values);

}  // namespace epitrack::tools
