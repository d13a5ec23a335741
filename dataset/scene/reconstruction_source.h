#pragma once
// For the files of dataset/scene/ only: the scene source of a reconstruction
// tool's output (geometry/reconstruction.h), shared by "monst3r", "vggt",
// "da3", "cut3r", "megasam" and "npz" (dataset/scene/monst3r.cc). Every tool
// goes through the MonST3R path: LiDAR scale fit, optional pose refinement,
// the paper's filters, camera-0 frame.

#include "dataset/scene/define.h"
#include "geometry/reconstruction.h"

namespace geodrive {

class ReconstructionSceneSource : public SceneSource {
 public:
  explicit ReconstructionSceneSource(ReconstructionFormat format)
      : format_(format) {}
  SceneSourceTraits Traits() const override;
  ConditionScene Build(const SceneInputs& in,
                       const SceneSourceOptions& options) const override;

 private:
  ReconstructionFormat format_;
};

// One class per registered source (the registry makes them by name).
#define GEODRIVE_RECONSTRUCTION_SOURCE(Class, format) \
  class Class : public ReconstructionSceneSource {    \
   public:                                            \
    Class() : ReconstructionSceneSource(format) {}    \
  }

GEODRIVE_RECONSTRUCTION_SOURCE(Monst3rSceneSource,
                               ReconstructionFormat::kMonst3r);

}  // namespace geodrive
