// Scene source "moge": a MoGe / MoGe-2 --maps folder (geometry/reconstruction
// .h), one image; the MonST3R path with the clip's camera trajectory
// (dataset/scene/reconstruction_source.h).

#include "dataset/scene/reconstruction_source.h"

namespace geodrive {
GEODRIVE_RECONSTRUCTION_SOURCE(MogeSceneSource, ReconstructionFormat::kMoge);
}  // namespace geodrive

GEODRIVE_DEFINE_SCENE_SOURCE(moge, geodrive::MogeSceneSource)
