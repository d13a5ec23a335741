// Names from data become paths in one place (geometry/util/names.h): hostile
// scene names, clip ids and manifest paths, each class of trick.

#include "geometry/util/names.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <set>
#include <string>
#include <vector>

#include "geometry/util/status.h"

namespace geodrive {
// A named namespace, not an anonymous one: the unity build compiles this
// file with others of its folder, whose anonymous helpers share names.
namespace names_test {

// What a result may hold: the kept bytes, '%' of an escape, '~' of a hash.
bool SafeBytes(const std::string& s) {
  for (size_t i = 0; i < s.size(); ++i) {
    const unsigned char c = s[i];
    const bool ok = std::isalnum(c) || c == '-' || c == '_' || c == '+' ||
                    c == '%' || c == '~' || (c == '.' && i > 0);
    if (!ok) return false;
  }
  return true;
}

TEST(PathComponentFromName, OrdinaryNamesAreUnchanged) {
  for (const char* n : {"scene-0916", "scene-0916_0006_kf", "a.b", "X+1"}) {
    EXPECT_EQ(PathComponentFromName(n), n);
    EXPECT_TRUE(IsPlainPathComponent(n));
  }
}

TEST(PathComponentFromName, HostileNamesBecomeOneSafeComponent) {
  const std::string nul("a\0b", 3);
  const std::string cases[] = {"../../escaped",
                               "..",
                               ".",
                               "a/b",
                               "/abs",
                               ".hidden",
                               "a\"b",
                               "q'uote",
                               "line\nbreak",
                               "tab\tx",
                               nul,
                               "back\\slash",
                               "sp ace",
                               "caf\xc3\xa9",
                               std::string(300, 'x'),
                               std::string(300, '/'),
                               "100%"};
  std::set<std::string> results;
  for (const std::string& n : cases) {
    const std::string c = PathComponentFromName(n);
    SCOPED_TRACE(c);
    EXPECT_TRUE(SafeBytes(c));
    EXPECT_TRUE(IsPlainPathComponent(c));
    EXPECT_LE(c.size(), kMaxNameComponentBytes);
    EXPECT_NE(c, ".");
    EXPECT_NE(c, "..");
    EXPECT_EQ(c.find('/'), std::string::npos);
    // One component, and it stays inside its folder.
    const std::filesystem::path p = std::filesystem::path("out") / c;
    EXPECT_EQ(p.lexically_normal().parent_path(), "out");
    results.insert(c);
  }
  // Injective: no two names share a folder.
  EXPECT_EQ(results.size(), std::size(cases));
  EXPECT_EQ(PathComponentFromName("../../escaped"), "%2E.%2F..%2Fescaped");
  EXPECT_EQ(PathComponentFromName("a/b"), "a%2Fb");
  EXPECT_EQ(PathComponentFromName("100%"), "100%25");
}

TEST(PathComponentFromName, LongNamesKeepAHashAndStayDistinct) {
  const std::string a(300, 'a');
  std::string b = a;
  b.back() = 'b';  // differs only after the cut
  const std::string ca = PathComponentFromName(a);
  const std::string cb = PathComponentFromName(b);
  EXPECT_EQ(ca.size(), kMaxNameComponentBytes);
  EXPECT_NE(ca, cb);
  EXPECT_EQ(ca, PathComponentFromName(a));  // stable
  // A cut never splits an escape: every '%' is followed by two hex digits.
  const std::string c = PathComponentFromName(std::string(300, '/'));
  for (size_t i = 0; i < c.size(); ++i) {
    if (c[i] == '%') {
      ASSERT_LT(i + 2, c.size());
      EXPECT_TRUE(std::isxdigit(static_cast<unsigned char>(c[i + 1])));
      EXPECT_TRUE(std::isxdigit(static_cast<unsigned char>(c[i + 2])));
    }
  }
}

TEST(PathComponentFromName, EmptyNameIsAnErrorNamingIt) {
  try {
    PathComponentFromName("", "scene.json: scene 3 name");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), "scene.json: scene 3 name: empty name");
  }
}

TEST(IsPlainPathComponent, RefusesWhatCouldClimbOrHide) {
  for (const std::string& n :
       std::vector<std::string>{"", ".", "..", ".x", "a/b", "a b", "a\"b",
                                std::string(201, 'a'), std::string("a\0", 2)})
    EXPECT_FALSE(IsPlainPathComponent(n)) << n;
}

TEST(CheckRelativePathInside, AcceptsPathsInsideRefusesTheRest) {
  EXPECT_NO_THROW(CheckRelativePathInside("pairs/scene-0001_0000", "m"));
  EXPECT_NO_THROW(CheckRelativePathInside("a..b/c", "m"));
  for (const std::string& bad : std::vector<std::string>{
           "", "/etc", "../x", "pairs/../../x", "pairs/..", "./x", "a//b", "a/",
           "a\nb", std::string("a\0b", 3)}) {
    EXPECT_THROW(CheckRelativePathInside(bad, "manifest.jsonl:3: pair_dir"),
                 InputError)
        << bad;
  }
  try {
    CheckRelativePathInside("../../x", "manifest.jsonl:3: pair_dir");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("manifest.jsonl:3: pair_dir"),
              std::string::npos);
    EXPECT_NE(std::string(e.what()).find("climbs out"), std::string::npos);
  }
}

TEST(CheckPathInside, GuardsTheOutputFolder) {
  EXPECT_NO_THROW(CheckPathInside("out/pairs/a", "out"));
  EXPECT_NO_THROW(CheckPathInside("out/pairs/../pairs/a", "out/"));
  EXPECT_THROW(CheckPathInside("out/pairs/../../x", "out"), InputError);
  EXPECT_THROW(CheckPathInside("/tmp/x", "out"), InputError);
  EXPECT_THROW(CheckPathInside("outside", "out"), InputError);
  EXPECT_THROW(CheckPathInside("out2/x", "out"), InputError);
}

}  // namespace names_test
}  // namespace geodrive
