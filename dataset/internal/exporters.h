#pragma once
// The exporters' constructors, one per file (dataset/export_<format>.cc), for
// CreateExporter (internal to geodrive_dataset).

#include <memory>

#include "dataset/exporter.h"

namespace geodrive {
namespace internal {

std::unique_ptr<Exporter> CreateGeodriveUpstreamExporter(
    const ExportOptions& options);
std::unique_ptr<Exporter> CreateStreetCrafterExporter(
    const ExportOptions& options);
std::unique_ptr<Exporter> CreateGen3cExporter(const ExportOptions& options);

}  // namespace internal
}  // namespace geodrive
