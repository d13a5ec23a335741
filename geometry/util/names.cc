#include "geometry/util/names.h"

#include <filesystem>

#include "geometry/util/hash.h"
#include "geometry/util/status.h"

namespace geodrive {

namespace {

bool KeptByte(unsigned char c, bool first) {
  if ((c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') ||
      (c >= '0' && c <= '9'))
    return true;
  if (c == '-' || c == '_' || c == '+') return true;
  return c == '.' && !first;
}

// Printable form of a name for error messages: control bytes escaped, at
// most 80 bytes.
std::string Printable(std::string_view s) {
  std::string o;
  for (unsigned char c : s.substr(0, 80)) {
    if (c < 0x20 || c == 0x7f) {
      static const char* hex = "0123456789ABCDEF";
      o += "\\x";
      o += hex[c >> 4];
      o += hex[c & 15];
    } else {
      o += static_cast<char>(c);
    }
  }
  if (s.size() > 80) o += "...";
  return o;
}

}  // namespace

std::string PathComponentFromName(std::string_view name,
                                  const std::string& what) {
  GEODRIVE_CHECK_INPUT(!name.empty(), what, ": empty name");
  static const char* hex = "0123456789ABCDEF";
  std::string out;
  out.reserve(name.size());
  for (size_t i = 0; i < name.size(); ++i) {
    const unsigned char c = static_cast<unsigned char>(name[i]);
    if (KeptByte(c, i == 0)) {
      out += static_cast<char>(c);
    } else {
      out += '%';
      out += hex[c >> 4];
      out += hex[c & 15];
    }
  }
  if (out.size() > kMaxNameComponentBytes) {
    // 1 + 16 bytes of suffix; cut before a "%XX" that would be split.
    size_t keep = kMaxNameComponentBytes - 17;
    if (keep >= 1 && out[keep - 1] == '%') keep -= 1;
    if (keep >= 2 && out[keep - 2] == '%') keep -= 2;
    out = out.substr(0, keep) + "~" + StableHash64(std::string(name));
  }
  return out;
}

bool IsPlainPathComponent(std::string_view name) {
  if (name.empty() || name.size() > kMaxPlainComponentBytes) return false;
  for (size_t i = 0; i < name.size(); ++i) {
    const unsigned char c = static_cast<unsigned char>(name[i]);
    if (!KeptByte(c, i == 0) && c != '%' && c != '~') return false;
  }
  return true;
}

void CheckRelativePathInside(const std::string& relative,
                             const std::string& what) {
  const std::string shown = "'" + Printable(relative) + "'";
  GEODRIVE_CHECK_INPUT(!relative.empty(), what, ": empty path");
  GEODRIVE_CHECK_INPUT(relative[0] != '/', what, ": ", shown,
                       " is absolute (expected a path inside the folder)");
  for (unsigned char c : relative) {
    GEODRIVE_CHECK_INPUT(c >= 0x20 && c != 0x7f, what, ": ", shown,
                         " holds a control byte");
  }
  size_t start = 0;
  while (start <= relative.size()) {
    size_t end = relative.find('/', start);
    if (end == std::string::npos) end = relative.size();
    const std::string_view part(relative.data() + start, end - start);
    GEODRIVE_CHECK_INPUT(!part.empty(), what, ": ", shown,
                         " has an empty path component");
    GEODRIVE_CHECK_INPUT(part != "." && part != "..", what, ": ", shown,
                         " climbs out of its folder ('", part, "' component)");
    start = end + 1;
  }
}

void CheckPathInside(const std::string& path, const std::string& root) {
  namespace fs = std::filesystem;
  const fs::path p = fs::absolute(path).lexically_normal();
  const fs::path r = fs::absolute(root).lexically_normal();
  const fs::path rel = p.lexically_relative(r);
  const bool inside = !rel.empty() && *rel.begin() != "..";
  GEODRIVE_CHECK_INPUT(inside, path,
                       ": would be written outside the output "
                       "folder ",
                       root);
}

}  // namespace geodrive
