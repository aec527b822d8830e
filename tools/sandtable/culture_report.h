#pragma once
// The culture load report's reasons (manifest build.culture.reasons), one
// line each: shared by `build` and `info` so both say the same.
#include <cstdint>
#include <cstdio>
#include <string>

#include <nlohmann/json.hpp>

namespace sandtable::cli {

/// "warning: N features dropped: REASON (e.g. SOURCE layer L feature FID)"
/// per reason; "note:" for the expected ones (outside, ignore rules).
inline void printCultureReasons(const nlohmann::json& culture, const char* indent) {
  if (!culture.is_object()) return;
  const auto it = culture.find("reasons");
  if (it == culture.end() || !it->is_object()) return;
  for (const auto& [key, r] : it->items()) {
    if (!r.is_object()) continue;
    const auto n = static_cast<unsigned long long>(r.value("count", std::uint64_t(0)));
    const std::string sample = r.value("sample", std::string());
    std::printf("%s%s: %llu feature%s %s: %s%s%s\n", indent, r.value("warning", true) ? "warning" : "note", n,
                n == 1 ? "" : "s", r.value("action", std::string("?")).c_str(), r.value("text", key).c_str(),
                sample.empty() ? "" : " (e.g. ", sample.empty() ? "" : (sample + ")").c_str());
  }
}

}  // namespace sandtable::cli
