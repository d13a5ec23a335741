// Scene source "npz": geometry/reconstruction.h's reader for this format,
// then the MonST3R path (dataset/scene/reconstruction_source.h).

#include "dataset/scene/reconstruction_source.h"

namespace geodrive {
GEODRIVE_RECONSTRUCTION_SOURCE(NpzSceneSource,
                               ReconstructionFormat::kGenericNpz);
}  // namespace geodrive

GEODRIVE_DEFINE_SCENE_SOURCE(npz, geodrive::NpzSceneSource)
