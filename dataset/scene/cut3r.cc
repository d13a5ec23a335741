// Scene source "cut3r": geometry/reconstruction.h's reader for this format,
// then the MonST3R path (dataset/scene/reconstruction_source.h).

#include "dataset/scene/reconstruction_source.h"

namespace geodrive {
GEODRIVE_RECONSTRUCTION_SOURCE(Cut3rSceneSource, ReconstructionFormat::kCut3r);
}  // namespace geodrive

GEODRIVE_DEFINE_SCENE_SOURCE(cut3r, geodrive::Cut3rSceneSource)
