// Scene source "da3": geometry/reconstruction.h's reader for this format,
// then the MonST3R path (dataset/scene/reconstruction_source.h).

#include "dataset/scene/reconstruction_source.h"

namespace geodrive {
GEODRIVE_RECONSTRUCTION_SOURCE(Da3SceneSource,
                               ReconstructionFormat::kDepthAnything3);
}  // namespace geodrive

GEODRIVE_DEFINE_SCENE_SOURCE(da3, geodrive::Da3SceneSource)
