#pragma once
// Checked readers for JSON fields, shared by our JSON file formats (trajectory
// JSON, boxes JSON). Internal: includes nlohmann/json, so only .cc files
// include it. Every failure throws InputError naming the file and the JSON
// location (`where`).

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>

#include "geometry/util/input_file.h"
#include "geometry/util/json_depth.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace internal {

// The top-level JSON object of a file (opened with InputFileStream: a folder,
// FIFO or device is refused naming the path; nesting deeper than kMaxJsonDepth
// is an error).
inline nlohmann::json ReadJsonObjectFile(const std::string& path) {
  InputFileStream in(path);
  nlohmann::json root;
  try {
    root = ParseJson(in, path);
  } catch (const nlohmann::json::exception& e) {
    ThrowInputError(path, "malformed JSON (", e.what(), ")");
  }
  if (!root.is_object())
    ThrowInputError(path, "top level must be a JSON object");
  return root;
}

// A finite number.
inline double JsonNumber(const std::string& path,
                         const nlohmann::json& j,
                         const std::string& where) {
  if (!j.is_number()) ThrowInputError(path, where, " is not a number");
  const double v = j.get<double>();
  if (!std::isfinite(v)) ThrowInputError(path, where, " is not finite");
  return v;
}

// An integer in [lo, hi], read in its own type: a JSON integer (3.0, 3.7
// and "3" are errors, not 3) whose value fits the range (2^32 + 1 for a
// 32-bit field is an error, never the 1 a cast would give).
inline int64_t JsonInt(const std::string& path,
                       const nlohmann::json& j,
                       const std::string& where,
                       int64_t lo,
                       int64_t hi) {
  if (!j.is_number_integer())
    ThrowInputError(path, where, " is not an integer");
  if (j.is_number_unsigned()) {
    const uint64_t u = j.get<uint64_t>();
    if (hi < 0 || u > static_cast<uint64_t>(hi) ||
        (lo > 0 && u < static_cast<uint64_t>(lo)))
      ThrowInputError(path, where, " = ", u, " is out of range [", lo, ", ", hi,
                      "]");
    return static_cast<int64_t>(u);
  }
  const int64_t v = j.get<int64_t>();
  if (v < lo || v > hi)
    ThrowInputError(path, where, " = ", v, " is out of range [", lo, ", ", hi,
                    "]");
  return v;
}

// The largest image side any reader accepts (camera width/height fields).
constexpr int64_t kMaxImageSide = 1 << 16;

// The string at `key` of `object`, `fallback` when the key is absent; any
// other type is an InputError (nlohmann's value() would throw its own
// type_error, which is not ours: found by fuzz_trajectory_json).
inline std::string JsonString(const std::string& path,
                              const nlohmann::json& object,
                              const std::string& key,
                              const std::string& fallback) {
  if (!object.contains(key)) return fallback;
  const nlohmann::json& v = object[key];
  if (!v.is_string()) ThrowInputError(path, "\"", key, "\" must be a string");
  return v.get<std::string>();
}

// An array of exactly N finite numbers.
template <int N>
Eigen::Matrix<double, N, 1> JsonVector(const std::string& path,
                                       const nlohmann::json& j,
                                       const std::string& where) {
  if (!j.is_array() || j.size() != N)
    ThrowInputError(path, where, " must be an array of ", N, " numbers");
  Eigen::Matrix<double, N, 1> v;
  for (int i = 0; i < N; ++i)
    v[i] = JsonNumber(path, j[i], where + "[" + std::to_string(i) + "]");
  return v;
}

}  // namespace internal
}  // namespace geodrive
