#pragma once
// `geodrive info FILE.tfrecord` (a Waymo Open Dataset v1 segment): the frame
// count, each frame's pose, the cameras' calibrations. Compiled into the
// commands plugin, not the executable: the Waymo reader links protobuf, which
// `geodrive --version` and `info` on other files must not load.

#include <string>

namespace geodrive {

// Prints what the TFRecord `path` holds (InputError naming the file and the
// record for a bad record or frame).
void DescribeWaymoSegment(const std::string& path);

// The plugin's exported form of DescribeWaymoSegment, found with
// LoadPluginSymbol (geometry/util/plugin.h).
constexpr char kDescribeWaymoSegmentSymbol[] = "GeodriveDescribeWaymoSegment";
using DescribeWaymoSegmentEntry = void (*)(const std::string& path);

}  // namespace geodrive
