// Scene source "megasam": geometry/reconstruction.h's reader for this format,
// then the MonST3R path (dataset/scene/reconstruction_source.h).

#include "dataset/scene/reconstruction_source.h"

namespace geodrive {
GEODRIVE_RECONSTRUCTION_SOURCE(MegasamSceneSource,
                               ReconstructionFormat::kMegaSam);
}  // namespace geodrive

GEODRIVE_DEFINE_SCENE_SOURCE(megasam, geodrive::MegasamSceneSource)
