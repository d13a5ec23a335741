// OUT/report.html (dataset/build_report.cc) from a hand-made build output:
// formatted numbers, "—" for missing values, escaped data, the failures, the
// pair table and video elements, and the same bytes for the same inputs. The
// page in a real browser: tests/apps/report_browser_test.py.

#include <gtest/gtest.h>

#include <filesystem>
#include <map>
#include <string>

#include "dataset/build_dataset.h"
#include "dataset/pairs.h"
#include "tests/common/test_util.h"

namespace geodrive {
// A named namespace, not an anonymous one: the unity build compiles this
// file with others of its folder, whose anonymous helpers share names.
namespace build_report_test {

namespace fs = std::filesystem;

int Count(const std::string& text, const std::string& what) {
  int n = 0;
  for (size_t p = text.find(what); p != std::string::npos;
       p = text.find(what, p + 1))
    ++n;
  return n;
}

// A pair folder with meta.json and stand-ins for its files; returns its
// manifest line.
std::string AddPair(const std::string& out,
                    const std::string& clip,
                    const std::string& geometry,
                    double scale,
                    const std::vector<double>& coverage,
                    const std::vector<std::optional<double>>& psnr) {
  const std::string dir = out + "/pairs/" + clip;
  fs::create_directories(dir);
  PairMeta m;
  m.clip_id = clip;
  m.scene_name = "scene-0001";
  m.scene_token = "token";
  m.intrinsics = PinholeCamera(500, 500, 360, 240, 720, 480);
  m.geometry_source = geometry;
  m.pose_units = geometry == "monst3r" ? "monst3r" : "metres";
  m.scale = scale;
  m.scale_source = geometry == "monst3r" ? "lidar" : "ego";
  m.preset = "paper";
  m.edit_mode = "3d";
  m.options_json = "{}";
  m.options_hash = "0123456789abcdef";
  m.quality.coverage = coverage;
  m.quality.psnr_static = psnr;
  for (const auto& [role, name] :
       std::map<std::string, std::string>{{"gt", "gt.mp4"},
                                          {"cond", "cond.mp4"},
                                          {"preview", "preview.png"},
                                          {"first_frame", "first_frame.png"}}) {
    m.files[role] = name;
    test::WriteFile(dir + "/" + name, "x");
  }
  test::WriteFile(dir + "/meta.json", PairMetaToJson(m));
  ManifestEntry e;
  e.clip_id = clip;
  e.pair_dir = "pairs/" + clip;
  e.scene_name = m.scene_name;
  e.num_frames = static_cast<int>(coverage.size());
  e.geometry_source = geometry;
  e.pose_units = m.pose_units;
  double sum = 0;
  for (double c : coverage) sum += c;
  e.mean_coverage = sum / coverage.size();
  e.options_hash = m.options_hash;
  return ManifestEntryToJson(e) + "\n";
}

std::string MakeOutput() {
  const std::string out = test::MakeTempDir("build_report");
  std::string manifest;
  manifest += AddPair(out, "scene-0001_0000", "monst3r", 1.2345,
                      {0.405058, 0.405058}, {23.31, std::nullopt, 23.29});
  manifest += AddPair(out, "scene-0001_0024", "lidar", 1.0, {0.5, 0.6},
                      {std::nullopt, std::nullopt});
  test::WriteFile(out + "/manifest.jsonl", manifest);
  test::WriteFile(
      out + "/failures.jsonl",
      FailureEntryToJson({"<script>alert('x')</script>", "geometry",
                          "pred_traj.txt: \"bad\" line 3 & <b>more</b>"}) +
          "\n");
  return out;
}

BuildDatasetSummary Summary() {
  BuildDatasetSummary s;
  s.clips_total = 3;
  s.built = 2;
  s.failed = 1;
  s.failures_by_stage["geometry"] = 1;
  s.seconds_total = 12.9387;
  s.seconds_by_stage = {
      {"geometry", 0.00391213}, {"cpu:geometry", 0.0031}, {"render", 253.4}};
  return s;
}

TEST(BuildReport, FormatsNumbersWithUnitsAndDashesForMissingValues) {
  const std::string out = MakeOutput();
  const BuildDatasetSummary s = Summary();
  WriteBuildReport(out, &s);
  const std::string html = test::ReadFile(out + "/report.html");
  // Counts, run time and stage times.
  EXPECT_NE(html.find("<dd id='count-pairs'>2</dd>"), std::string::npos);
  EXPECT_NE(html.find("<dd id='count-failed'>1</dd>"), std::string::npos);
  EXPECT_NE(html.find(">12.9 s<"), std::string::npos);
  EXPECT_NE(html.find(">0.004 s<"), std::string::npos);
  EXPECT_NE(html.find(">253 s (4.2 min)<"), std::string::npos);
  EXPECT_EQ(html.find("0.00391213"), std::string::npos);
  EXPECT_EQ(html.find("12.9387"), std::string::npos);
  // Per pair: coverage with 3 decimals (raw value for sorting), PSNR mean
  // over the frames with one, the scale of MonST3R poses.
  EXPECT_NE(html.find("data-v='0.405058'>0.405<"), std::string::npos);
  EXPECT_NE(html.find(">23.3 dB<"), std::string::npos);
  EXPECT_NE(html.find(">1.23 m/unit<"), std::string::npos);
  // The lidar pair has neither PSNR nor scale; the failed clip has no values.
  EXPECT_NE(html.find("<td class='n' title='metric geometry (ego)'>—</td>"),
            std::string::npos);
  EXPECT_EQ(Count(html, "class='pair-row'"), 2);
  EXPECT_EQ(Count(html, "class='fail-row'"), 1);
  // Histograms with count and value ticks.
  EXPECT_GE(Count(html, "<svg viewBox="), 3);
  EXPECT_GE(Count(html, "class='yt'"), 6);
  EXPECT_GE(Count(html, "class='xt'"), 6);
  // Self-contained: no network reference.
  EXPECT_EQ(html.find("http://"), std::string::npos);
  EXPECT_EQ(html.find("https://"), std::string::npos);
}

TEST(BuildReport, EscapesDataAndListsFailuresWithMessages) {
  const std::string out = MakeOutput();
  WriteBuildReport(out, nullptr);
  const std::string html = test::ReadFile(out + "/report.html");
  EXPECT_EQ(html.find("<script>alert"), std::string::npos);
  EXPECT_EQ(html.find("<b>more"), std::string::npos);
  EXPECT_NE(html.find("&lt;script&gt;alert(&#39;x&#39;)&lt;/script&gt;"),
            std::string::npos);
  EXPECT_NE(
      html.find("<pre class='msg'>pred_traj.txt: &quot;bad&quot; line 3 &amp; "
                "&lt;b&gt;more&lt;/b&gt;</pre>"),
      std::string::npos);
  EXPECT_EQ(Count(html, "<li id='failure-"), 1);
  // Only the page's own script.
  EXPECT_EQ(Count(html, "<script>"), 1);
}

TEST(BuildReport, VideosSideBySideOverThePreviewStrip) {
  const std::string out = MakeOutput();
  WriteBuildReport(out, nullptr);
  const std::string html = test::ReadFile(out + "/report.html");
  EXPECT_EQ(Count(html, "<article class='card'"), 2);
  EXPECT_NE(html.find("<video class='gt' controls muted playsinline "
                      "preload='metadata' src='pairs/scene-0001_0000/gt.mp4'"),
            std::string::npos);
  EXPECT_NE(html.find("src='pairs/scene-0001_0000/cond.mp4'"),
            std::string::npos);
  // The first frame as the ground truth's poster, the preview as the
  // fallback of browsers without video, and the preview strip under both.
  EXPECT_NE(html.find("poster='pairs/scene-0001_0000/first_frame.png'><img "
                      "src='pairs/scene-0001_0000/preview.png'"),
            std::string::npos);
  EXPECT_EQ(Count(html,
                  "<figure class='strip'><img loading='lazy' "
                  "src='pairs/scene-0001_0000/preview.png'"),
            1);
}

TEST(BuildReport, SameInputsGiveTheSameBytes) {
  const std::string out = MakeOutput();
  const BuildDatasetSummary s = Summary();
  WriteBuildReport(out, &s);
  const std::string first = test::ReadFile(out + "/report.html");
  WriteBuildReport(out, &s);
  EXPECT_EQ(test::ReadFile(out + "/report.html"), first);
}

TEST(BuildReport, AnEmptyOutputStillGivesAPage) {
  const std::string out = test::MakeTempDir("build_report_empty");
  WriteBuildReport(out, nullptr);
  const std::string html = test::ReadFile(out + "/report.html");
  EXPECT_NE(html.find("<dd id='count-pairs'>0</dd>"), std::string::npos);
  EXPECT_NE(html.find("no values"), std::string::npos);
  EXPECT_NE(html.find("No clip failed."), std::string::npos);
}

}  // namespace build_report_test
}  // namespace geodrive
