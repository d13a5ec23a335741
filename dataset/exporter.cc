// The exporter factory and the format names (dataset/exporter.h).

#include "dataset/exporter.h"

#include <algorithm>

#include "dataset/internal/exporters.h"
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
  }
  ThrowInputError("--export", "unknown format");
}

void CheckClipForExport(const Exporter& exporter,
                        const std::string& clip_id,
                        int num_frames) {
  const ExportRequirements req = exporter.Requirements();
  const std::string name = ToString(exporter.Format());
  GEODRIVE_CHECK_INPUT(req.exact_frames <= 0 || num_frames == req.exact_frames,
                       clip_id, ": ", name, " needs ", req.exact_frames,
                       " frames; this clip has ", num_frames);
  GEODRIVE_CHECK_INPUT(num_frames >= req.min_frames, clip_id, ": ", name,
                       " needs ", req.min_frames, " frames; this clip has ",
                       num_frames);
}

}  // namespace geodrive
