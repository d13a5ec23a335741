#pragma once
// The adapters' constructors, for OpenDriveDataset (dataset/drive_dataset.h).

#include <memory>

#include "dataset/drive_dataset.h"

namespace geodrive {

// dataset/waymo_adapter.cc: TFRecord segments of Waymo v1 frames.
std::unique_ptr<DriveDataset> OpenWaymoDriveDataset(
    const DriveDatasetOptions& options);

}  // namespace geodrive
