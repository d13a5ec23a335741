#pragma once
// Names from data become paths in one place. A scene name, a clip id, a file
// name from a table or a manifest is text someone else wrote: "../../x",
// "a/b", ".hidden", a NUL or a newline, 300 bytes. Every writer that puts
// such a name into a path goes through PathComponentFromName; every reader
// that follows a relative path from a file (a manifest's pair_dir, a meta's
// file names) checks it with CheckRelativePathInside. docs/RELIABILITY.md,
// class "names from data become paths".

#include <string>
#include <string_view>

namespace geodrive {

// The longest path component PathComponentFromName returns (bytes). Linux
// allows 255; the rest leaves room for suffixes writers add (".tmp<pid>_<n>",
// "_kf", "_0012").
constexpr size_t kMaxNameComponentBytes = 160;

// `name` as one safe path component, injective and stable:
//  - bytes A-Z a-z 0-9 '-' '_' '+' and '.' (not as the first byte) are kept;
//  - every other byte ('/', '\\', '%', quotes, spaces, control bytes, NUL,
//    non-ASCII) and a leading '.' become "%XX" (upper-case hex), so ".",
//    "..", ".hidden" and "a/../b" can never name another folder;
//  - a result longer than kMaxNameComponentBytes keeps its first bytes and
//    ends in "~" + the 16-hex-digit FNV-1a hash of the whole name.
// Ordinary names ("scene-0916", "scene-0916_0006_kf") come back unchanged.
// Throws InputError naming `what` when `name` is empty.
std::string PathComponentFromName(std::string_view name,
                                  const std::string& what = "name");

// The longest component IsPlainPathComponent accepts: an encoded name plus
// the suffixes ids add ("_0012_r10_kf", "~<token>").
constexpr size_t kMaxPlainComponentBytes = 200;

// True when `name` is 1..kMaxPlainComponentBytes bytes of what
// PathComponentFromName keeps or writes (A-Z a-z 0-9 - _ + % ~, '.' not
// first): safe as a folder name.
bool IsPlainPathComponent(std::string_view name);

// Checks a relative path read from a file (`what` names the file and field):
// not empty, not absolute, no "." or ".." component, no NUL or control
// bytes, no empty component; so `root + "/" + relative` stays inside root.
// Throws InputError "<what>: '<relative>' ..." otherwise.
void CheckRelativePathInside(const std::string& relative,
                             const std::string& what);

// Throws InputError unless `path`, made absolute and lexically normal, is
// `root` or inside it (the last guard of every writer: nothing is written
// outside --out).
void CheckPathInside(const std::string& path, const std::string& root);

}  // namespace geodrive
