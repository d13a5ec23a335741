#pragma once
// The exporters' constructors, one per file (dataset/export_<format>.cc), for
// CreateExporter (internal to geodrive_dataset).

#include <memory>
#include <set>
#include <string>
#include <vector>

#include "dataset/exporter.h"

namespace geodrive {
namespace internal {

std::unique_ptr<Exporter> CreateGeodriveUpstreamExporter(
    const ExportOptions& options);
std::unique_ptr<Exporter> CreateStreetCrafterExporter(
    const ExportOptions& options);
std::unique_ptr<Exporter> CreateGen3cExporter(const ExportOptions& options);
std::unique_ptr<Exporter> CreateRdsHqExporter(const ExportOptions& options);
std::unique_ptr<Exporter> CreateDrivestudioExporter(
    const ExportOptions& options);

// The pair folders under `out`/pairs that hold an export's `folder` (finished
// pairs only: not hidden, with their meta.json), by name.
std::vector<std::string> PairsWithExport(const std::string& out,
                                         const std::string& folder);

// Scenes for validation: the first round(fraction * scenes) in the order of a
// seeded hash of their names (independent of the clip order), leaving at
// least one scene for training when the fraction is below 1.
std::set<std::string> ValScenes(const std::set<std::string>& scenes,
                                const ExportOptions& options);

}  // namespace internal
}  // namespace geodrive
