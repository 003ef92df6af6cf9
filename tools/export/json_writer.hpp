#pragma once

// A tiny JSON text builder for summary.json: objects, arrays, strings (escaped) and numbers, where
// a non-finite number is written as null (JSON has no NaN or infinity).

#include <cstdint>
#include <string>

namespace epitrack::io {

class JsonWriter {
 public:
  void beginObject() { open('{'); }
  void endObject() { close('}'); }
  void beginArray() { open('['); }
  void endArray() { close(']'); }
  /// The key of the next value in the current object.
  void key(const std::string& name);
  void value(double number);
  void value(int64_t number);
  void value(int number) { value(static_cast<int64_t>(number)); }
  void value(bool flag);
  void value(const std::string& text);
  void value(const char* text) { value(std::string(text)); }
  void null();
  template <typename T>
  void field(const std::string& name, const T& v) {
    key(name);
    value(v);
  }
  [[nodiscard]] const std::string& text() const { return out_; }

  /// `text` as a JSON string literal (quotes included).
  static std::string quote(const std::string& text);
  /// Shortest round-trip-safe decimal ("%.17g" trimmed to "%.15g" when that round-trips), or null.
  static std::string number(double v);

 private:
  void open(char c);
  void close(char c);
  void beforeValue();

  std::string out_;
  int depth_ = 0;
  bool first_ = true;       // no element yet at this level
  bool after_key_ = false;  // a key was just written
};

}  // namespace epitrack::io
