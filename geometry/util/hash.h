#pragma once
// Stable content hashes (same text -> same hash on every machine and run).

#include <string>

namespace geodrive {

// FNV-1a 64 of `text` as 16 lower-case hex digits (e.g. options_hash of a
// pair: which content options built it).
std::string StableHash64(const std::string& text);

}  // namespace geodrive
