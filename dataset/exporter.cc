// The exporter factory and the format names (dataset/exporter.h).

#include "dataset/exporter.h"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "dataset/internal/exporters.h"
#include "geometry/util/hash.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace {

struct FormatName {
  ExportFormat format;
  const char* name;
};
constexpr FormatName kFormatNames[] = {
    {ExportFormat::kGeodriveUpstream, "geodrive-upstream"},
    {ExportFormat::kStreetCrafter, "streetcrafter"},
    {ExportFormat::kGen3c, "gen3c"},
    {ExportFormat::kRdsHq, "rds-hq"},
    {ExportFormat::kDrivestudio, "drivestudio"},
};

}  // namespace

std::vector<ExportFormat> AllExportFormats() {
  std::vector<ExportFormat> formats;
  for (const FormatName& f : kFormatNames) formats.push_back(f.format);
  return formats;
}

std::string ToString(ExportFormat format) {
  for (const FormatName& f : kFormatNames)
    if (f.format == format) return f.name;
  return "unknown";
}

ExportFormat ParseExportFormat(const std::string& text) {
  std::string names;
  for (const FormatName& f : kFormatNames) {
    if (text == f.name) return f.format;
    names += std::string(names.empty() ? "" : ", ") + f.name;
  }
  ThrowInputError("--export", "unknown format '", text, "' (formats: ", names,
                  ")");
}

std::vector<ExportFormat> ParseExportFormats(const std::string& text) {
  std::vector<ExportFormat> formats;
  if (text.empty() || text == "none") return formats;
  size_t start = 0;
  while (start <= text.size()) {
    const size_t comma = std::min(text.find(',', start), text.size());
    formats.push_back(ParseExportFormat(text.substr(start, comma - start)));
    start = comma + 1;
  }
  std::sort(formats.begin(), formats.end());
  formats.erase(std::unique(formats.begin(), formats.end()), formats.end());
  return formats;
}

std::string ToString(const std::vector<ExportFormat>& formats) {
  std::string text;
  for (const ExportFormat f : formats)
    text += (text.empty() ? "" : ",") + ToString(f);
  return text;
}

bool ExportOptions::Check() const {
  return val_fraction >= 0 && val_fraction <= 1;
}

std::unique_ptr<Exporter> CreateExporter(ExportFormat format,
                                         const ExportOptions& options) {
  GEODRIVE_CHECK_INPUT(options.Check(),
                       "--val-fraction must be in [0, 1], got ",
                       options.val_fraction);
  switch (format) {
    case ExportFormat::kGeodriveUpstream:
      return internal::CreateGeodriveUpstreamExporter(options);
    case ExportFormat::kStreetCrafter:
      return internal::CreateStreetCrafterExporter(options);
    case ExportFormat::kGen3c:
      return internal::CreateGen3cExporter(options);
    case ExportFormat::kRdsHq:
      return internal::CreateRdsHqExporter(options);
    case ExportFormat::kDrivestudio:
      return internal::CreateDrivestudioExporter(options);
  }
  ThrowInputError("--export", "unknown format");
}

bool AcceptsFrameCount(const ExportRequirements& req, int num_frames) {
  if (req.exact_frames > 0 && num_frames != req.exact_frames) return false;
  if (num_frames < req.min_frames) return false;
  return req.frame_step <= 0 ||
         (num_frames - req.min_frames) % req.frame_step == 0;
}

std::string FrameCountText(const ExportRequirements& req) {
  if (req.exact_frames > 0) return std::to_string(req.exact_frames) + " frames";
  if (req.frame_step <= 0) return std::to_string(req.min_frames) + " frames";
  const int first = req.min_frames, step = req.frame_step;
  const int offset = first % step;
  std::string text = std::to_string(first) + ", " +
                     std::to_string(first + step) + ", ... frames (" +
                     std::to_string(step) + " N";
  if (offset > 0) text += " + " + std::to_string(offset);
  return text + ")";
}

void Exporter::CheckClip(const std::string& clip_id, int num_frames) const {
  CheckClipForExport(*this, clip_id, num_frames);
}

void Exporter::WriteRig(const std::vector<ExportClip>& views,
                        const std::string& pair_dir,
                        PairMeta* meta) const {
  (void)meta;
  ThrowInputError(views.empty() ? pair_dir : views.front().clip_id, ": ",
                  ToString(Format()),
                  " is single-camera (its trainer reads one camera's clips); "
                  "drop --cameras or the format");
}

void CheckClipForExport(const Exporter& exporter,
                        const std::string& clip_id,
                        int num_frames) {
  const ExportRequirements req = exporter.Requirements();
  GEODRIVE_CHECK_INPUT(AcceptsFrameCount(req, num_frames), clip_id, ": ",
                       ToString(exporter.Format()), " needs ",
                       FrameCountText(req), "; this clip has ", num_frames);
}

namespace internal {

std::vector<std::string> PairsWithExport(const std::string& out,
                                         const std::string& folder) {
  namespace fs = std::filesystem;
  std::vector<std::string> names;
  if (!fs::is_directory(out + "/pairs")) return names;
  for (const auto& e : fs::directory_iterator(out + "/pairs")) {
    const std::string name = e.path().filename().string();
    if (e.is_directory() && name.rfind(".", 0) != 0 &&
        fs::exists(e.path() / "meta.json") &&
        fs::is_directory(e.path() / folder))
      names.push_back(name);
  }
  std::sort(names.begin(), names.end());
  return names;
}

std::set<std::string> ValScenes(const std::set<std::string>& scenes,
                                const ExportOptions& options) {
  std::vector<std::pair<std::string, std::string>> order;
  for (const std::string& s : scenes) {
    order.emplace_back(
        StableHash64(std::to_string(options.split_seed) + "/" + s), s);
  }
  std::sort(order.begin(), order.end());
  size_t n = static_cast<size_t>(
      std::lround(options.val_fraction * static_cast<double>(scenes.size())));
  if (options.val_fraction < 1 && n >= scenes.size() && n > 0)
    n = scenes.size() - 1;
  std::set<std::string> val;
  for (size_t i = 0; i < n && i < order.size(); ++i)
    val.insert(order[i].second);
  return val;
}

}  // namespace internal
}  // namespace geodrive
