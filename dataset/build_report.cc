// OUT/report.html of `build-dataset`: one self-contained page (inline CSS and
// script, no network) with the counts, time per stage, quality histograms, a
// sortable per-pair table, the failures and each pair's videos.

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <optional>
#include <sstream>
#include <tuple>

#include "dataset/build_dataset.h"
#include "dataset/pairs.h"
#include "geodrive_version.h"
#include "geometry/util/files.h"

namespace geodrive {

namespace fs = std::filesystem;

namespace {

// Pairs with video players; the table lists every pair.
constexpr size_t kMaxVideoCards = 60;

// Text and attribute values.
std::string Html(const std::string& s) {
  std::string o;
  o.reserve(s.size());
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
      case '\'':
        o += "&#39;";
        break;
      default:
        o += c;
    }
  }
  return o;
}

// A relative path as a URL (each byte outside the unreserved set and '/'
// percent-encoded), HTML-escaped for an attribute.
std::string Url(const std::string& path) {
  static const char* kHex = "0123456789ABCDEF";
  std::string o;
  for (unsigned char c : path) {
    if (std::isalnum(c) || c == '-' || c == '_' || c == '.' || c == '~' ||
        c == '/') {
      o += static_cast<char>(c);
    } else {
      o += '%';
      o += kHex[c >> 4];
      o += kHex[c & 15];
    }
  }
  return Html(o);
}

std::string Fixed(double v, int decimals) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*f", decimals, v);
  return buf;
}

// Up to `digits` significant digits, trailing zeros dropped ("0.25", "45").
std::string Short(double v, int digits = 4) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*g", digits, v);
  return buf;
}

// "0.253 s", "2.53 s", "12.9 s", "253 s (4.2 min)", "9000 s (2.5 h)".
std::string Seconds(double s) {
  if (!std::isfinite(s)) return "—";
  const double a = std::abs(s);
  std::string text;
  if (a < 1) {
    text = Fixed(s, 3);
  } else if (a < 10) {
    text = Fixed(s, 2);
  } else if (a < 100) {
    text = Fixed(s, 1);
  } else {
    text = Fixed(s, 0);
  }
  text += " s";
  if (a >= 7200) {
    text += " (" + Fixed(s / 3600, 1) + " h)";
  } else if (a >= 120) {
    text += " (" + Fixed(s / 60, 1) + " min)";
  }
  return text;
}

// A step of 1, 2 or 5 times a power of ten giving at most `max_ticks`
// intervals over `range`.
double NiceStep(double range, int max_ticks) {
  if (!(range > 0)) return 1;
  const double raw = range / max_ticks;
  const double p = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0, 10.0}) {
    if (m * p >= raw * (1 - 1e-9)) return m * p;
  }
  return 10 * p;
}

struct Histogram {
  std::string title;    // the figure's caption (full, wraps)
  std::string x_label;  // axis title under the x axis
  std::string y_label;  // what is counted ("pairs", "frames")
  double lo = 0, hi = 1;
  int bins = 20;
};

// An inline SVG histogram of `values` in a figure: count axis with ticks on
// the left, value ticks under the bars, the axis titles inside the SVG and
// the full caption as HTML (never clipped). Scales with its container.
std::string SvgHistogram(const std::vector<double>& values,
                         const Histogram& h) {
  std::vector<int> counts(h.bins, 0);
  int n = 0, clamped = 0;
  for (double v : values) {
    if (!std::isfinite(v)) continue;
    const int b =
        static_cast<int>(std::floor((v - h.lo) / (h.hi - h.lo) * h.bins));
    if (b < 0 || b >= h.bins) {
      // The top edge belongs to the last bin.
      if (!(b == h.bins && v <= h.hi)) ++clamped;
    }
    counts[std::clamp(b, 0, h.bins - 1)]++;
    ++n;
  }
  std::ostringstream os;
  os << "<figure class='hist'>";
  if (n == 0) {
    os << "<div class='empty'>no values</div>";
  } else {
    const int maxc = *std::max_element(counts.begin(), counts.end());
    const double ystep = std::max(1.0, NiceStep(maxc, 5));
    const double ytop = std::max(ystep, std::ceil(maxc / ystep) * ystep);
    // Plot area inside a 320 x 196 view box.
    const double x0 = 46, x1 = 310, y0 = 10, y1 = 146;
    const double pw = x1 - x0, ph = y1 - y0;
    auto xpos = [&](double v) { return x0 + (v - h.lo) / (h.hi - h.lo) * pw; };
    auto ypos = [&](double c) { return y1 - c / ytop * ph; };
    os << "<svg viewBox='0 0 320 196' role='img' aria-label='" << Html(h.title)
       << "'>";
    // Count axis: grid lines and labels.
    os << "<g class='grid'>";
    for (double c = 0; c <= ytop + 1e-9; c += ystep) {
      const std::string y = Fixed(ypos(c), 1);
      os << "<line x1='" << x0 << "' x2='" << x1 << "' y1='" << y << "' y2='"
         << y << "'/><text class='yt' x='" << x0 - 6 << "' y='" << y << "'>"
         << Short(c) << "</text>";
    }
    os << "</g>";
    // Bars, each with its range and count as a tooltip.
    const double bw = pw / h.bins;
    for (int b = 0; b < h.bins; ++b) {
      if (counts[b] == 0) continue;
      const double top = ypos(counts[b]);
      const double blo = h.lo + (h.hi - h.lo) * b / h.bins;
      const double bhi = h.lo + (h.hi - h.lo) * (b + 1) / h.bins;
      os << "<rect class='bar' x='" << Fixed(x0 + b * bw + 0.5, 1) << "' y='"
         << Fixed(top, 1) << "' width='" << Fixed(bw - 1, 1) << "' height='"
         << Fixed(y1 - top, 1) << "'><title>" << Short(blo) << "–" << Short(bhi)
         << ": " << counts[b] << " " << Html(h.y_label) << "</title></rect>";
    }
    // Value axis: baseline, ticks and labels.
    os << "<line class='axis' x1='" << x0 << "' x2='" << x1 << "' y1='" << y1
       << "' y2='" << y1 << "'/><line class='axis' x1='" << x0 << "' x2='" << x0
       << "' y1='" << y0 << "' y2='" << y1 << "'/>";
    const double xstep = NiceStep(h.hi - h.lo, 5);
    for (double v = std::ceil(h.lo / xstep - 1e-9) * xstep;
         v <= h.hi + xstep * 1e-6; v += xstep) {
      const std::string x = Fixed(xpos(v), 1);
      os << "<line class='axis' x1='" << x << "' x2='" << x << "' y1='" << y1
         << "' y2='" << y1 + 4 << "'/><text class='xt' x='" << x << "' y='"
         << y1 + 19 << "'>" << Short(std::abs(v) < xstep * 1e-6 ? 0 : v)
         << "</text>";
    }
    os << "<text class='xl' x='" << (x0 + x1) / 2 << "' y='192'>"
       << Html(h.x_label) << "</text><text class='yl' transform='translate(13 "
       << (y0 + y1) / 2 << ") rotate(-90)'>" << Html(h.y_label)
       << "</text></svg>";
  }
  os << "<figcaption>" << Html(h.title) << " <span class='muted'>(" << n << " "
     << Html(h.y_label);
  if (clamped)
    os << "; " << clamped << " outside the axis, counted in the end bins";
  os << ")</span></figcaption></figure>";
  return os.str();
}

// What the report shows of one pair (from meta.json; absent when it does not
// read).
struct PairRow {
  ManifestEntry entry;
  std::optional<PairMeta> meta;
  std::optional<double> psnr_mean;  // over the frames that have one
  std::optional<double> scale;      // metres per MonST3R unit
  std::string scale_note;           // tooltip where there is no scale
  std::string video_ratio;          // CSS aspect-ratio of the videos
  // URLs relative to OUT ("" = none).
  std::string gt, cond, preview, first_frame;
};

// A surround-view pair's cameras (frame-0 coverage) and seam check (the
// fraction of overlap pixels whose depths agree within 1 %), one paragraph;
// "" for a single-camera pair.
std::string RigSummary(const PairMeta& m) {
  if (m.views.size() < 2) return "";
  std::ostringstream os;
  os << "<p class='rig muted'>cameras, frame-0 coverage: ";
  for (size_t k = 0; k < m.views.size(); ++k) {
    const PairView& v = m.views[k];
    os << (k ? ", " : "") << Html(v.channel) << " "
       << (v.coverage.empty() ? std::string("&ndash;")
                              : Fixed(v.coverage.front(), 3));
  }
  os << "<br>seams, depths within 1 % of the overlap: ";
  if (m.seams.empty()) os << "no overlap with depth at frame 0";
  for (size_t k = 0; k < m.seams.size(); ++k) {
    const PairSeam& s = m.seams[k];
    os << (k ? ", " : "") << Html(s.camera_a) << "&ndash;" << Html(s.camera_b)
       << " " << Fixed(s.agreeing_fraction, 3) << " (" << s.overlap_pixels
       << " px)";
  }
  os << "</p>";
  return os.str();
}

// The URL of a pair's file role when meta.json lists it and it exists.
std::string PairFileUrl(const std::string& out,
                        const ManifestEntry& e,
                        const PairMeta& m,
                        const std::string& role) {
  const auto it = m.files.find(role);
  if (it == m.files.end()) return "";
  const std::string rel = e.pair_dir + "/" + it->second;
  std::error_code ec;
  if (!fs::is_regular_file(out + "/" + rel, ec)) return "";
  return Url(rel);
}

constexpr const char* kStyle = R"CSS(
:root{--fg:#1d232b;--muted:#5d6875;--line:#d9dee4;--bg:#fff;--soft:#f4f6f8;--accent:#2f6db3;--bad:#b3261e}
*{box-sizing:border-box}
body{font:15px/1.45 system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;color:var(--fg);background:var(--bg);margin:0 auto;padding:16px;max-width:1200px}
h1{font-size:1.5em;margin:.2em 0}h2{font-size:1.2em;margin:1.6em 0 .5em;border-bottom:1px solid var(--line);padding-bottom:.2em}
h3{font-size:1em;margin:0 0 .4em}
code,pre,.mono{font-family:ui-monospace,SFMono-Regular,Menlo,Consolas,monospace;font-size:.9em}
code{overflow-wrap:anywhere}
.muted{color:var(--muted)}
a{color:var(--accent)}
.stats{display:grid;grid-template-columns:repeat(auto-fill,minmax(150px,1fr));gap:8px;margin:0}
.stats div{background:var(--soft);border-radius:6px;padding:8px 10px}
.stats dt{color:var(--muted);font-size:.85em}.stats dd{margin:0;font-size:1.35em;font-variant-numeric:tabular-nums}
.stats .bad dd{color:var(--bad)}
.scroll{overflow-x:auto;-webkit-overflow-scrolling:touch;max-width:100%}
table{border-collapse:collapse;font-variant-numeric:tabular-nums}
th,td{padding:4px 10px;border-bottom:1px solid var(--line);text-align:left;white-space:nowrap}
td.n,th.n{text-align:right}
thead th{background:var(--soft);position:sticky;top:0}
th button{font:inherit;font-weight:600;background:none;border:0;padding:0;cursor:pointer;color:inherit}
th button::after{content:" \2195";color:var(--muted);font-weight:400}
th[aria-sort=ascending] button::after{content:" \2191";color:var(--fg)}
th[aria-sort=descending] button::after{content:" \2193";color:var(--fg)}
tr.fail-row td{color:var(--bad)}
.bar-cell{min-width:80px}.bar-cell span{display:block;height:8px;background:#9bb8d8;border-radius:2px}
.hists{display:grid;grid-template-columns:repeat(auto-fill,minmax(260px,1fr));gap:12px}
figure{margin:0}
figure.hist{background:var(--soft);border-radius:6px;padding:8px}
figure.hist svg{width:100%;height:auto;display:block}
figure.hist .empty{padding:40px 0;text-align:center;color:var(--muted)}
figcaption{font-size:.9em;margin-top:4px}
svg text{font-size:13px;fill:var(--fg)}
svg .yt{text-anchor:end;dominant-baseline:middle}svg .xt,svg .xl,svg .yl{text-anchor:middle}
svg .xl,svg .yl{font-size:13px;fill:var(--muted)}
svg .grid line{stroke:#e2e6ea}svg .axis{stroke:#6b7480}svg .bar{fill:#4a7fb5}
img.wide{width:100%;max-width:1200px;height:auto;border:1px solid var(--line)}
ol.failures{padding-left:1.4em}
ol.failures li{margin:.4em 0}
ol.failures pre{white-space:pre-wrap;overflow-wrap:anywhere;background:#fbf0ef;border-radius:4px;padding:6px 8px;margin:.2em 0 0}
.stage{display:inline-block;background:#f3d9d6;color:var(--bad);border-radius:3px;padding:0 6px;font-size:.85em}
.cards{display:grid;gap:16px}
.card{border:1px solid var(--line);border-radius:6px;padding:10px}
.vids{display:grid;grid-template-columns:repeat(auto-fit,minmax(280px,1fr));gap:8px}
.vids video,.vids img{width:100%;height:auto;display:block;background:#000;border-radius:3px}
nav{display:flex;flex-wrap:wrap;gap:4px 14px;font-size:.95em}
.novideo{display:flex;align-items:center;justify-content:center;aspect-ratio:3/2;background:var(--soft);border-radius:3px;padding:8px;text-align:center}
figure.strip{margin-top:8px}figure.strip img{width:100%;height:auto;display:block}
.note{background:#fff6dc;border:1px solid #ecd9a0;border-radius:4px;padding:6px 10px}
@media (max-width:600px){body{padding:10px;font-size:14px}th,td{padding:3px 6px}}
)CSS";

// Sorts the pair table by a column (numbers from data-v; rows without one
// stay last in either direction; ties keep the clip order), and turns the
// videos into links where the browser cannot play H.264.
constexpr const char* kScript = R"JS(
(function () {
  var table = document.getElementById('pair-table');
  if (table) {
    var heads = table.tHead.rows[0].cells;
    Array.prototype.forEach.call(heads, function (th, col) {
      var button = th.querySelector('button');
      if (!button) return;
      button.addEventListener('click', function () {
        var asc = th.getAttribute('aria-sort') !== 'ascending';
        var num = th.getAttribute('data-type') === 'num';
        var body = table.tBodies[0];
        var rows = Array.prototype.slice.call(body.rows);
        rows.sort(function (a, b) {
          var x = a.cells[col], y = b.cells[col];
          var c = 0;
          if (num) {
            var xh = x.hasAttribute('data-v'), yh = y.hasAttribute('data-v');
            if (xh !== yh) return xh ? -1 : 1;
            if (xh) c = parseFloat(x.getAttribute('data-v')) -
                        parseFloat(y.getAttribute('data-v'));
          } else {
            var xs = x.textContent, ys = y.textContent;
            c = xs < ys ? -1 : xs > ys ? 1 : 0;
          }
          if (!asc) c = -c;
          return c || (+a.getAttribute('data-i') - +b.getAttribute('data-i'));
        });
        rows.forEach(function (r) { body.appendChild(r); });
        Array.prototype.forEach.call(heads, function (h) {
          if (h !== th) h.removeAttribute('aria-sort');
        });
        th.setAttribute('aria-sort', asc ? 'ascending' : 'descending');
      });
    });
  }
  // Videos the browser cannot play become links to their files.
  function unplayable(video) {
    var div = document.createElement('div');
    div.className = 'novideo';
    var link = document.createElement('a');
    link.href = video.getAttribute('src');
    link.textContent = video.getAttribute('aria-label') + ' (H.264 MP4)';
    div.appendChild(document.createTextNode('Not playable here: '));
    div.appendChild(link);
    video.parentNode.replaceChild(div, video);
  }
  var videos = Array.prototype.slice.call(document.querySelectorAll('video'));
  var probe = document.createElement('video');
  if (!probe.canPlayType('video/mp4; codecs="avc1.42E01E"')) {
    videos.forEach(unplayable);
    if (videos.length) document.getElementById('codec-note').hidden = false;
  } else {
    videos.forEach(function (v) {
      if (v.error) unplayable(v);
      else v.addEventListener('error', function () { unplayable(v); });
    });
  }
})();
)JS";

// The report's sections, in page order, over the build's manifest, failures
// and pair metas (Collect). Members keep the names the sections use.
class ReportWriter {
 public:
  ReportWriter(const std::string& out, const BuildDatasetSummary* summary)
      : out(out), summary(summary) {}

  std::string Write() {
    Collect();
    Header();
    Counts();
    Quality();
    Pairs();
    Failures();
    Videos();
    TimePerStage();
    os << "<script>" << kScript << "</script></body></html>\n";
    return os.str();
  }

 private:
  // Per pair: meta.json figures; over pairs: the histograms' values.
  void Collect() {
    if (fs::exists(out + "/manifest.jsonl"))
      entries = ReadManifest(out + "/manifest.jsonl");
    if (fs::exists(out + "/failures.jsonl"))
      fails = ReadFailures(out + "/failures.jsonl");

    // Per pair: meta.json figures; over pairs: the histograms' values.
    for (const auto& e : entries) {
      PairRow r;
      r.entry = e;
      coverage.push_back(e.mean_coverage);
      try {
        r.meta = ReadPairMeta(out + "/" + e.pair_dir);
      } catch (const std::exception&) {
      }
      if (r.meta) {
        const PairMeta& m = *r.meta;
        if (!m.quality.coverage.empty())
          coverage0_by_source[m.geometry_source].push_back(
              m.quality.coverage.front());
        if (completion_url.empty()) {
          completion_url = PairFileUrl(out, e, m, "completion_preview");
          if (!completion_url.empty()) completion_clip = e.clip_id;
        }
        // The LiDAR-fitted scale of MonST3R geometry; otherwise why none.
        if (m.scale_source == "lidar") {
          r.scale = m.scale;
        } else if (m.pose_units == "monst3r") {
          r.scale_note = "no metric scale: poses in MonST3R units";
        } else {
          r.scale_note = "metric geometry (" + m.scale_source + ")";
        }
        if (m.scale_source == "lidar") scales.push_back(m.scale);
        double sum = 0;
        int n = 0;
        for (const auto& p : m.quality.psnr_static) {
          if (!p || !std::isfinite(*p)) continue;
          psnr.push_back(*p);
          sum += *p;
          ++n;
        }
        if (n) r.psnr_mean = sum / n;
        if (m.intrinsics.width > 0 && m.intrinsics.height > 0) {
          r.video_ratio = std::to_string(m.intrinsics.width) + "/" +
                          std::to_string(m.intrinsics.height);
        }
        r.gt = PairFileUrl(out, e, m, "gt");
        r.cond = PairFileUrl(out, e, m, "cond");
        r.preview = PairFileUrl(out, e, m, "preview");
        r.first_frame = PairFileUrl(out, e, m, "first_frame");
      }
      rows.push_back(std::move(r));
    }
  }

  // The page head, the output folder and the section links.
  void Header() {
    has_time = summary && !summary->seconds_by_stage.empty();
    os << "<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>"
          "<meta name='viewport' content='width=device-width, initial-scale=1'>"
          "<link rel='icon' href='data:,'>"
          "<title>geodrive build-dataset report</title><style>"
       << kStyle << "</style></head><body>\n";
    os << "<header><h1>Dataset build report</h1><p class='muted'>Output "
          "<code>"
       << Html(fs::absolute(out).lexically_normal().string())
       << "</code> &middot; geodrive " << Html(GEODRIVE_VERSION)
       << "</p><nav><a href='#counts'>counts</a> <a "
          "href='#quality'>quality</a> "
          "<a href='#pairs'>pairs</a> <a href='#failures'>failures ("
       << fails.size() << ")</a> <a href='#videos'>videos</a>"
       << (has_time ? " <a href='#time'>time per stage</a>" : "")
       << "</nav></header>\n";
  }

  void Counts() {
    // Counts.
    auto stat = [this](const std::string& id, const std::string& name,
                       const std::string& value, bool bad = false) {
      os << "<div" << (bad ? " class='bad'" : "") << "><dt>" << Html(name)
         << "</dt><dd id='" << id << "'>" << value << "</dd></div>";
    };
    os << "<section id='counts'><h2>Counts</h2><dl class='stats'>";
    stat("count-pairs", "pairs", std::to_string(entries.size()));
    stat("count-failed", "failed clips", std::to_string(fails.size()),
         !fails.empty());
    if (summary) {
      stat("count-clips", "clips in this run",
           std::to_string(summary->clips_total));
      stat("count-built", "built in this run", std::to_string(summary->built));
      stat("count-skipped", "skipped (already built)",
           std::to_string(summary->skipped_existing));
      if (summary->skipped_no_monst3r)
        stat("count-no-monst3r", "skipped (no MonST3R folder)",
             std::to_string(summary->skipped_no_monst3r));
      if (summary->rebuilt_broken)
        stat("count-rebuilt-broken", "rebuilt (broken)",
             std::to_string(summary->rebuilt_broken));
      if (summary->rebuilt_mismatched)
        stat("count-rebuilt-options", "rebuilt (other options)",
             std::to_string(summary->rebuilt_mismatched));
      if (summary->kept_mismatched)
        stat("count-kept-options", "kept (other options)",
             std::to_string(summary->kept_mismatched));
      if (summary->log_write_errors)
        stat("count-log-errors", "log write errors",
             std::to_string(summary->log_write_errors), true);
      stat("run-time", "run time", Html(Seconds(summary->seconds_total)));
    }
    os << "</dl>";
    if (summary && summary->interrupted)
      os << "<p class='note'>The run was interrupted: rerun to resume.</p>";
    os << "</section>\n";
  }

  void Quality() {
    // Quality.
    os << "<section id='quality'><h2>Quality</h2>";
    if (summary && summary->quality.pairs)
      os << "<p id='quality-brief'>" << Html(summary->quality.BriefReport())
         << "</p>";
    os << "<div class='hists'>"
       << SvgHistogram(coverage, {"Mean condition coverage per pair",
                                  "fraction of pixels with a condition value",
                                  "pairs", 0, 1, 20})
       << SvgHistogram(psnr, {"Static-region PSNR per frame (dB), condition vs "
                              "ground truth",
                              "PSNR (dB)", "frames", 5, 45, 20});
    for (const auto& [source, values] : coverage0_by_source) {
      os << SvgHistogram(values,
                         {"frame-0 coverage per pair, --geometry " + source,
                          "frame-0 coverage", "pairs", 0, 1, 20});
    }
    if (!scales.empty()) {
      const double lo = *std::min_element(scales.begin(), scales.end());
      const double hi = *std::max_element(scales.begin(), scales.end());
      os << SvgHistogram(scales, {"LiDAR scale (metres per MonST3R unit)",
                                  "metres per MonST3R unit", "pairs", lo * 0.9,
                                  hi * 1.1 + 1e-9, 20});
    }
    os << "</div></section>\n";

    if (!completion_url.empty()) {
      os << "<section id='completion'><h2>Depth completion, before and after ("
         << Html(completion_clip) << ", frame 0)</h2><figure><img class='wide' "
         << "src='" << completion_url << "' alt='depth completion of "
         << Html(completion_clip)
         << "'><figcaption>The frame-0 image, the LiDAR returns projected into "
            "it, and the completed depth (colour: inverse depth, 2 m red to "
            "80 m blue; black: none).</figcaption></figure></section>\n";
    }
  }

  void Pairs() {
    // Pairs and failed clips, one row each.
    os << "<section id='pairs'><h2>Pairs</h2><p class='muted'>"
       << entries.size() << " pairs, " << fails.size()
       << " failed clips. Click a column title to sort; coverage and PSNR are "
          "means over the clip's frames, PSNR over the static rendered "
          "pixels.</p><div class='scroll'><table id='pair-table'><thead><tr>"
          "<th><button type='button'>clip</button></th>"
          "<th><button type='button'>scene</button></th>"
          "<th><button type='button'>geometry</button></th>"
          "<th class='n' data-type='num'><button type='button'>frames</button>"
          "</th><th class='n' data-type='num' id='sort-coverage'><button "
          "type='button'>coverage</button></th>"
          "<th class='n' data-type='num'><button type='button'>PSNR</button>"
          "</th><th class='n' data-type='num'><button type='button'>scale"
          "</button></th><th><button type='button'>failure</button></th>"
          "<th>videos</th></tr></thead><tbody>";
    int index = 0;
    for (size_t k = 0; k < rows.size(); ++k) {
      const PairRow& r = rows[k];
      const ManifestEntry& e = r.entry;
      os << "<tr class='pair-row' data-i='" << index++ << "' data-clip='"
         << Html(e.clip_id) << "'><td><code>" << Html(e.clip_id)
         << "</code></td><td>" << Html(e.scene_name) << "</td><td>"
         << Html(e.geometry_source) << "</td><td class='n' data-v='"
         << e.num_frames << "'>" << e.num_frames
         << "</td><td class='n' data-v='" << Fixed(e.mean_coverage, 6) << "'>"
         << Fixed(e.mean_coverage, 3) << "</td>";
      if (r.psnr_mean) {
        os << "<td class='n' data-v='" << Fixed(*r.psnr_mean, 3) << "'>"
           << Fixed(*r.psnr_mean, 1) << " dB</td>";
      } else {
        os << "<td class='n'>—</td>";
      }
      if (r.scale) {
        os << "<td class='n' data-v='" << Short(*r.scale, 6) << "'>"
           << Fixed(*r.scale, 2) << " m/unit</td>";
      } else {
        os << "<td class='n'";
        if (!r.scale_note.empty())
          os << " title='" << Html(r.scale_note) << "'";
        os << ">—</td>";
      }
      os << "<td>—</td><td>";
      if (k < kMaxVideoCards && (!r.gt.empty() || !r.cond.empty())) {
        os << "<a href='#pair-" << k << "'>watch</a>";
      } else {
        bool any = false;
        for (const auto& [name, url] :
             {std::pair<std::string, std::string>("gt", r.gt),
              {"cond", r.cond}}) {
          if (url.empty()) continue;
          os << (any ? " &middot; " : "") << "<a href='" << url << "'>" << name
             << "</a>";
          any = true;
        }
        if (!any) os << "—";
      }
      os << "</td></tr>";
    }
    for (size_t k = 0; k < fails.size(); ++k) {
      const FailureEntry& f = fails[k];
      os << "<tr class='fail-row' data-i='" << index++ << "' data-clip='"
         << Html(f.clip_id) << "'><td><code>" << Html(f.clip_id)
         << "</code></td><td>—</td><td>—</td><td class='n'>—</td>"
            "<td class='n'>—</td><td class='n'>—</td><td class='n'>—</td>"
            "<td><a href='#failure-"
         << k << "'>" << Html(f.stage) << "</a></td><td>—</td></tr>";
    }
    os << "</tbody></table></div></section>\n";
  }

  void Failures() {
    // Failures with their messages.
    os << "<section id='failures'><h2>Failures</h2>";
    if (fails.empty()) {
      os << "<p class='muted'>No clip failed.</p>";
    } else {
      if (summary && !summary->failures_by_stage.empty()) {
        os << "<p>In this run:";
        for (const auto& [stage, n] : summary->failures_by_stage)
          os << " <span class='stage'>" << Html(stage) << "</span> " << n;
        os << "</p>";
      }
      os << "<ol class='failures'>";
      for (size_t k = 0; k < fails.size(); ++k) {
        const FailureEntry& f = fails[k];
        os << "<li id='failure-" << k << "' data-clip='" << Html(f.clip_id)
           << "'><code class='clip'>" << Html(f.clip_id)
           << "</code> <span class='stage'>" << Html(f.stage)
           << "</span><pre class='msg'>" << Html(f.error) << "</pre></li>";
      }
      os << "</ol>";
    }
    os << "</section>\n";
  }

  void Videos() {
    // Each pair's ground truth and condition videos, side by side (stacked in
    // a narrow window), over its preview strip (the fallback where the videos
    // do not play).
    os << "<section id='videos'><h2>Ground truth and condition videos</h2>";
    const size_t cards = std::min(rows.size(), kMaxVideoCards);
    if (rows.size() > cards) {
      os << "<p class='muted'>Players for the first " << cards << " of "
         << rows.size()
         << " pairs (by clip id); the table links every pair's videos.</p>";
    }
    os << "<p class='note' id='codec-note' hidden>This browser cannot play "
          "H.264 video: the players are replaced by links to the files; each "
          "pair's preview strip shows its frames.</p><div class='cards'>";
    for (size_t k = 0; k < cards; ++k) {
      const PairRow& r = rows[k];
      if (r.gt.empty() && r.cond.empty()) continue;
      const std::string clip = Html(r.entry.clip_id);
      os << "<article class='card' id='pair-" << k << "' data-clip='" << clip
         << "'><h3><code>" << clip << "</code> <span class='muted'>"
         << Html(r.entry.scene_name) << " &middot; " << r.entry.num_frames
         << " frames &middot; coverage " << Fixed(r.entry.mean_coverage, 3);
      if (r.psnr_mean)
        os << " &middot; PSNR " << Fixed(*r.psnr_mean, 1) << " dB";
      os << "</span></h3>";
      if (r.meta) os << RigSummary(*r.meta);
      os << "<div class='vids'>";
      for (const auto& [role, label, url, poster] :
           {std::tuple<std::string, std::string, std::string, std::string>(
                "gt", "ground truth", r.gt, r.first_frame),
            {"cond", "condition", r.cond, ""}}) {
        os << "<figure>";
        if (url.empty()) {
          os << "<div class='muted'>no " << label << " video</div>";
        } else {
          os << "<video class='" << role
             << "' controls muted playsinline preload='metadata' src='" << url
             << "' aria-label='" << label << " of " << clip << "'";
          if (!r.video_ratio.empty())
            os << " style='aspect-ratio:" << r.video_ratio << "'";
          if (!poster.empty()) os << " poster='" << poster << "'";
          os << ">";
          if (!r.preview.empty())
            os << "<img src='" << r.preview << "' alt='preview of " << clip
               << "'>";
          os << "<a href='" << url << "'>" << label << " video</a></video>";
        }
        os << "<figcaption>" << label << "</figcaption></figure>";
      }
      os << "</div>";
      if (!r.preview.empty()) {
        os << "<figure class='strip'><img loading='lazy' src='" << r.preview
           << "' alt='preview of " << clip
           << "'><figcaption>Every third frame: ground truth (top), condition "
              "(bottom).</figcaption></figure>";
      }
      os << "</article>";
    }
    os << "</div></section>\n";
  }

  void TimePerStage() {
    // Time per stage: wall and worker-thread CPU seconds (keys "cpu:<stage>",
    // written by dataset/pair_builder.cc; the scale fit's CPU is inside
    // geometry's), with each stage's share of the wall time.
    if (has_time) {
      const std::string cpu = "cpu:";
      const auto& stages = summary->seconds_by_stage;
      double wall_total = 0;
      for (const auto& [s, t] : stages)
        if (s.rfind(cpu, 0) != 0) wall_total += t;
      os << "<section id='time'><h2>Time per stage</h2><p class='muted'>"
            "Summed over clips (threads in parallel: the sum can exceed the "
            "run "
            "time).</p><div class='scroll'><table><thead><tr><th>stage</th>"
            "<th class='n'>wall</th><th class='n'>CPU</th><th>share of wall"
            "</th></tr></thead><tbody>";
      for (const auto& [s, t] : stages) {
        if (s.rfind(cpu, 0) == 0) continue;
        const auto c = stages.find(cpu + s);
        const double share = wall_total > 0 ? t / wall_total : 0;
        os << "<tr><th>" << Html(s) << "</th><td class='n'>" << Html(Seconds(t))
           << "</td><td class='n'>"
           << (c != stages.end() ? Html(Seconds(c->second)) : "—")
           << "</td><td class='bar-cell' title='" << Fixed(100 * share, 1)
           << " %'><span style='width:" << Fixed(100 * share, 1)
           << "%'></span></td></tr>";
      }
      os << "</tbody></table></div></section>\n";
    }
  }

  const std::string out;
  const BuildDatasetSummary* const summary;
  std::vector<ManifestEntry> entries;
  std::vector<FailureEntry> fails;
  std::vector<PairRow> rows;
  std::vector<double> coverage, scales, psnr;
  std::map<std::string, std::vector<double>> coverage0_by_source;
  std::string completion_url, completion_clip;
  bool has_time = false;
  std::ostringstream os;
};

}  // namespace

void WriteBuildReport(const std::string& out,
                      const BuildDatasetSummary* summary) {
  WriteFileAtomic(out + "/report.html", ReportWriter(out, summary).Write());
}

}  // namespace geodrive
