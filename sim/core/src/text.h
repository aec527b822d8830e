#pragma once
// What the simulator's line readers (scripts, scenarios, aircraft files,
// collision tables) share: the words of a line with their columns, numbers
// read from a whole word, and the pieces of their messages. Internal to
// sandtable_sim (not installed).
//
// Thread safety: pure functions.
#include <charconv>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "sandtable/base/result.h"
#include "sandtable/formats/bytes.h"

namespace sandtable::sim::text {

/// A whole text file of at most `maxBytes` (formats' readSmallFile), or a
/// problem "<prefix>cannot open <what>: <why>; check the path".
inline Result<std::string> readText(const std::string& path, std::uint64_t maxBytes, const std::string& what,
                                    const std::string& prefix = {}) {
  auto bytes = readSmallFile(path, maxBytes);
  if (!bytes) {
    std::string m = prefix;
    m += "cannot open ";
    m += what;
    m += ": ";
    m += bytes.message();
    m += "; check the path";
    return Problem{path, 0, m};
  }
  const auto& b = bytes.value();
  return std::string(reinterpret_cast<const char*>(b.data()), b.size());
}

/// The line of `text` that starts at `pos`, without its "\n" or "\r\n";
/// `pos` moves to the start of the next line (past the end after the last).
inline std::string_view nextLine(std::string_view text, std::size_t& pos) {
  std::size_t end = text.find('\n', pos);
  if (end == std::string_view::npos) end = text.size();
  std::string_view line = text.substr(pos, end - pos);
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  pos = end + 1;
  return line;
}

/// The column of a line's first control character (a byte below 0x20
/// other than tab, or 0x7F), or npos: the readers take plain text only.
inline std::size_t findControl(std::string_view line) {
  for (std::size_t k = 0; k < line.size(); ++k) {
    const auto c = static_cast<unsigned char>(line[k]);
    if ((c < 0x20 && c != '\t') || c == 0x7F) return k;
  }
  return std::string_view::npos;
}

/// A word of a line and where it starts.
struct Token {
  std::string_view text;
  std::size_t column = 0;  ///< 0-based byte offset in the line
};

/// Where a comment starts.
enum class Comment : std::uint8_t {
  word,      ///< at a word that starts with '#'; a '#' inside a word is part of it
  anywhere,  ///< at any '#', which also ends the word before it
};

inline bool isSpace(char c) { return c == ' ' || c == '\t'; }

/// The words of a line, separated by spaces and tabs, up to the comment.
/// `end` receives the column just past the last word (0 when there is
/// none): where a missing word would go.
inline std::vector<Token> tokenize(std::string_view line, std::size_t& end, Comment comment = Comment::word) {
  const bool hashEndsWord = comment == Comment::anywhere;
  std::vector<Token> out;
  std::size_t k = 0;
  end = 0;
  while (k < line.size()) {
    while (k < line.size() && isSpace(line[k])) ++k;
    if (k == line.size() || line[k] == '#') break;
    const std::size_t start = k;
    while (k < line.size() && !isSpace(line[k]) && !(hashEndsWord && line[k] == '#')) ++k;
    out.push_back({line.substr(start, k - start), start});
    end = k;
  }
  return out;
}

inline std::vector<Token> tokenize(std::string_view line, Comment comment = Comment::word) {
  std::size_t end = 0;
  return tokenize(line, end, comment);
}

/// The whole word as a finite double, or false ("12abc", "nan", "inf",
/// "" fail); `out` is left alone on failure.
inline bool finiteNumber(std::string_view s, double& out) {
  double v = 0;
  const char* last = s.data() + s.size();
  const auto [p, ec] = std::from_chars(s.data(), last, v);
  if (ec != std::errc() || p != last || !std::isfinite(v)) return false;
  out = v;
  return true;
}

inline std::optional<double> finiteNumber(std::string_view s) {
  double v = 0;
  if (!finiteNumber(s, v)) return std::nullopt;
  return v;
}

/// Decimal digits only (no sign, no space), 1 to `maxDigits` of them, with
/// a value of at most `max`; `out` is left alone on failure. 20 digits
/// hold 18446744073709551615; a longer word is refused even when its
/// leading zeros would make it fit.
inline bool unsignedNumber(std::string_view s, std::uint64_t max, std::uint64_t& out, std::size_t maxDigits = 20) {
  if (s.empty() || s.size() > maxDigits) return false;
  std::uint64_t v = 0;
  for (char c : s) {
    if (c < '0' || c > '9') return false;
    const auto d = static_cast<std::uint64_t>(c - '0');
    if (d > max || v > (max - d) / 10) return false;  // v * 10 + d > max, without overflowing
    v = v * 10 + d;
  }
  out = v;
  return true;
}

inline std::optional<std::uint64_t> unsignedNumber(std::string_view s, std::uint64_t max) {
  std::uint64_t v = 0;
  if (!unsignedNumber(s, max, v)) return std::nullopt;
  return v;
}


/// `s` in double quotes, for messages. Call it text::quoted: unqualified,
/// a std::string argument finds std::quoted (<iomanip>) by argument-
/// dependent lookup.
inline std::string quoted(std::string_view s) {
  std::string q = "\"";
  q += s;
  q += '"';
  return q;
}

/// A number for messages: "%.6g" (0.1, 12.5, 1e+06).
inline std::string shortNumber(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

/// "control character 0x1B": how a message names the byte.
inline std::string controlCharacter(char c) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "control character 0x%02X", static_cast<unsigned>(static_cast<unsigned char>(c)));
  return buf;
}

/// "line N, column M: what", the house form of a problem's message;
/// `line` counts from 1, `column` from 0 (shown from 1).
inline std::string lineColumnMessage(std::size_t line, std::size_t column, std::string_view what) {
  std::string m = "line ";
  m += std::to_string(line);
  m += ", column ";
  m += std::to_string(column + 1);
  m += ": ";
  m += what;
  return m;
}

}  // namespace sandtable::sim::text
