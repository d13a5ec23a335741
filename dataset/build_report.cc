// OUT/report.html of `build-dataset` (counts, timing, histograms, previews,
// failures).

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <sstream>

#include "dataset/build_dataset.h"
#include "dataset/pairs.h"
#include "geodrive_version.h"
#include "geometry/util/files.h"

namespace geodrive {

namespace fs = std::filesystem;

namespace {

std::string Html(const std::string& s) {
  std::string o;
  for (char c : s) {
    switch (c) {
      case '<':
        o += "&lt;";
        break;
      case '>':
        o += "&gt;";
        break;
      case '&':
        o += "&amp;";
        break;
      case '"':
        o += "&quot;";
        break;
      default:
        o += c;
    }
  }
  return o;
}

// An inline SVG histogram of `values` over [lo, hi] with `bins` bins.
std::string SvgHistogram(const std::vector<double>& values,
                         double lo,
                         double hi,
                         int bins,
                         const std::string& label) {
  std::vector<int> counts(bins, 0);
  for (double v : values) {
    if (!std::isfinite(v)) continue;
    int b = static_cast<int>((v - lo) / (hi - lo) * bins);
    counts[std::clamp(b, 0, bins - 1)]++;
  }
  const int maxc = std::max(1, *std::max_element(counts.begin(), counts.end()));
  std::ostringstream os;
  const int w = 360, h = 140;
  os << "<svg width='" << w << "' height='" << h + 30
     << "' style='background:#fafafa'>";
  for (int b = 0; b < bins; ++b) {
    const double bh = static_cast<double>(counts[b]) / maxc * h;
    os << "<rect x='" << b * w / bins + 1 << "' y='" << h - bh << "' width='"
       << w / bins - 2 << "' height='" << bh << "' fill='#4a7fb5'><title>"
       << counts[b] << "</title></rect>";
  }
  os << "<text x='0' y='" << h + 14 << "' font-size='11'>" << lo
     << "</text><text x='" << w - 30 << "' y='" << h + 14 << "' font-size='11'>"
     << hi << "</text><text x='120' y='" << h + 27 << "' font-size='12'>"
     << Html(label) << "</text></svg>";
  return os.str();
}

}  // namespace

void WriteBuildReport(const std::string& out,
                      const BuildDatasetSummary* summary) {
  std::vector<ManifestEntry> entries;
  if (fs::exists(out + "/manifest.jsonl"))
    entries = ReadManifest(out + "/manifest.jsonl");
  std::vector<FailureEntry> fails;
  if (fs::exists(out + "/failures.jsonl"))
    fails = ReadFailures(out + "/failures.jsonl");
  std::vector<double> coverage, scales, psnr;
  // Frame-0 coverage per geometry source, and the first pair with a
  // depth-completion preview (lidar-dense: before / after).
  std::map<std::string, std::vector<double>> coverage0_by_source;
  std::string completion_pair, completion_clip;
  for (const auto& e : entries) {
    coverage.push_back(e.mean_coverage);
    try {
      const PairMeta m = ReadPairMeta(out + "/" + e.pair_dir);
      if (!m.quality.coverage.empty())
        coverage0_by_source[m.geometry_source].push_back(
            m.quality.coverage.front());
      if (completion_pair.empty() && m.files.count("completion_preview")) {
        completion_pair = e.pair_dir + "/" + m.files.at("completion_preview");
        completion_clip = e.clip_id;
      }
      if (m.scale_source == "lidar") scales.push_back(m.scale);
      for (const auto& p : m.quality.psnr_static)
        if (p) psnr.push_back(*p);
    } catch (const std::exception&) {
    }
  }
  std::ostringstream os;
  os << "<!DOCTYPE html><html><head><meta charset='utf-8'><title>geodrive "
        "build-dataset report"
        "</"
        "title><style>body{font-family:sans-serif;margin:24px}td,th{padding:"
        "2px 8px;text-align:"
        "left}img{width:100%;max-width:900px;border:1px solid "
        "#ccc}.grid{display:grid;grid-"
        "template-columns:repeat(auto-fill,minmax(420px,1fr));gap:12px}</"
        "style></head><body>";
  os << "<h1>Dataset build report</h1><p>Output: <code>"
     << Html(fs::absolute(out).string()) << "</code> &middot; geodrive "
     << GEODRIVE_VERSION << "</p>";
  os << "<h2>Counts</h2><table><tr><th>pairs</th><td>" << entries.size()
     << "</td></tr><tr><th>failed clips</th><td>" << fails.size()
     << "</td></tr>";
  if (summary) {
    os << "<tr><th>built in the last run</th><td>" << summary->built
       << "</td></tr><tr><th>skipped (already built)</th><td>"
       << summary->skipped_existing
       << "</td></tr><tr><th>skipped (no MonST3R folder)</th><td>"
       << summary->skipped_no_monst3r
       << "</td></tr><tr><th>run time (s)</th><td>" << summary->seconds_total
       << "</td></tr>";
  }
  os << "</table>";
  if (summary && !summary->seconds_by_stage.empty()) {
    // Wall and worker-thread CPU seconds (keys "cpu:<stage>", written by
    // dataset/pair_builder.cc; the scale fit's CPU is inside geometry's).
    const std::string cpu = "cpu:";
    const auto& stages = summary->seconds_by_stage;
    os << "<h2>Time per stage (s, summed over clips)</h2><table>"
       << "<tr><th>stage</th><th>wall</th><th>CPU</th></tr>";
    for (const auto& [s, t] : stages) {
      if (s.rfind(cpu, 0) == 0) continue;
      const auto c = stages.find(cpu + s);
      os << "<tr><th>" << Html(s) << "</th><td>" << t << "</td><td>";
      if (c != stages.end()) os << c->second;
      os << "</td></tr>";
    }
    os << "</table>";
  }
  os << "<h2>Quality</h2>"
     << SvgHistogram(coverage, 0, 1, 20, "mean coverage per pair") << " "
     << SvgHistogram(psnr, 5, 45, 20, "static-region PSNR per frame (dB)");
  for (const auto& [source, values] : coverage0_by_source) {
    os << " "
       << SvgHistogram(values, 0, 1, 20,
                       "frame-0 coverage per pair, --geometry " + source);
  }
  if (summary && summary->quality.pairs)
    os << "<p>" << Html(summary->quality.BriefReport()) << "</p>";
  if (!completion_pair.empty()) {
    os << "<h2>Depth completion, before and after (" << Html(completion_clip)
       << ", frame 0)</h2><figure><img src='" << Html(completion_pair)
       << "'><figcaption>the frame-0 image, the LiDAR returns projected into "
          "it, and the completed depth (colour: inverse depth, 2 m red to "
          "80 m blue; black: none)</figcaption></figure>";
  }
  if (!scales.empty()) {
    const double lo = *std::min_element(scales.begin(), scales.end());
    const double hi = *std::max_element(scales.begin(), scales.end());
    os << " "
       << SvgHistogram(scales, lo * 0.9, hi * 1.1 + 1e-9, 20,
                       "LiDAR scale (metres per MonST3R unit)");
  }
  if (!fails.empty()) {
    os << "<h2>Failures</h2><table><tr><th>clip</th><th>stage</th><th>error</"
          "th></tr>";
    for (const auto& f : fails) {
      os << "<tr><td>" << Html(f.clip_id) << "</td><td>" << Html(f.stage)
         << "</td><td>" << Html(f.error) << "</td></tr>";
    }
    os << "</table>";
  }
  os << "<h2>Previews (GT above condition)</h2><div class='grid'>";
  size_t shown = 0;
  for (const auto& e : entries) {
    if (++shown > 60) break;
    os << "<figure><img src='" << Html(e.pair_dir)
       << "/preview.png' loading='lazy'><figcaption>" << Html(e.clip_id)
       << " &middot; coverage " << e.mean_coverage << "</figcaption></figure>";
  }
  os << "</div></body></html>\n";
  WriteFileAtomic(out + "/report.html", os.str());
}

}  // namespace geodrive
