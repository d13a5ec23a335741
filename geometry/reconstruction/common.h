#pragma once
// For the readers of geometry/reconstruction/ only: arrays of an npz checked
// and converted to MonST3R's conventions, each failure one InputError naming
// the file and the array.

#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "geometry/camera.h"
#include "geometry/monst3r.h"
#include "geometry/npz.h"
#include "geometry/reconstruction.h"
#include "geometry/rigid3.h"

namespace geodrive {
namespace reconstruction {

// A tool's confidence scale.
enum class ConfidenceScale {
  kUnit,     // already in [0, 1] (clamped)
  kOnePlus,  // c in [1, inf): 1 + exp(x) (VGGT, DA3) or DUSt3R's (CUT3R);
             // conf01 = 1 - 1/c
  kLog,      // v = log(c): conf01 = 1 - exp(-v) (MonST3R conf_*.npy)
  kLogit,    // sigmoid(v) (pi3)
};
// "unit", "1+exp", "log", "logit"; Parse throws InputError naming `what`.
std::string ToString(ConfidenceScale scale);
ConfidenceScale ParseConfidenceScale(const std::string& text,
                                     const std::string& what);

// Array `key` of `npz` with its declared size checked against the options
// first; `required` false returns nullopt when absent.
std::optional<NpyArray> ReadArray(const NpzReader& npz,
                                  const std::string& key,
                                  const ReconstructionReadOptions& options,
                                  bool required = true);

// (N, H, W) or (N, H, W, 1) numeric -> N CV_32FC1 maps (float16 exactly).
// Depths: `depth` true rejects +inf (float16 overflow: "N depths overflow")
// and NaN-only maps; negatives and zeros stay (invalid pixels downstream).
// Taken by value: a float32 array passed as an rvalue is not copied.
std::vector<cv::Mat> FloatMaps(NpyArray array,
                               const std::string& what,
                               bool depth);
// The same from one .npy file ((H, W) or (H, W, 1)).
cv::Mat FloatMapFromNpy(const std::string& path,
                        bool depth,
                        const ReconstructionReadOptions& options);
// Confidence maps converted to [0, 1].
std::vector<cv::Mat> ConfidenceMaps(const NpyArray& array,
                                    const std::string& what,
                                    ConfidenceScale scale);
cv::Mat ConfidenceToUnit(const cv::Mat& map, ConfidenceScale scale);

// Poses (N, 3, 4), (N, 4, 4) (or (3, 4) / (4, 4) for N = 1) -> world_from_cam.
// `w2c` true inverts them (cam_from_world files). Rejects non-finite values,
// a bottom row other than [0 0 0 1], rotations with |R^T R - I| > 1e-3 and
// reflections (det < 0: "OpenGL-flipped axes?").
std::vector<Rigid3d> Poses(const NpyArray& array,
                           const std::string& what,
                           bool w2c);
// One 4x4 or 3x4 pose from a small array (CUT3R's camera/*.npz).
Rigid3d PoseFromMatrix(const double* m, int rows, const std::string& what);

// Intrinsics (N, 3, 3) or (3, 3) shared -> one camera per frame on a
// width x height grid (integer-index pixels). Rejects non-finite or
// non-positive focals and a last row other than [0 0 1].
std::vector<PinholeCamera> Cameras(const NpyArray& array,
                                   const std::string& what,
                                   int num_frames,
                                   int width,
                                   int height);

// Images: (N, H, W, 3) uint8, or (N, 3, H, W) / (N, H, W, 3) float in [0, 1]
// (VGGT) -> N CV_8UC3 RGB.
std::vector<cv::Mat> Images(const NpyArray& array, const std::string& what);

// Throws InputError when the camera centre moves backwards along its own
// optical axis at every step with motion (at least 3 such steps): the
// signature of cam_from_world poses read as world_from_cam. `hint` says
// what to do.
void CheckMotionDirection(const std::vector<Rigid3d>& world_from_cam,
                          const std::string& what,
                          const std::string& hint);

// The in-memory reconstruction from per-frame arrays (empty vectors for
// absent ones); sizes checked against the depth maps.
struct Arrays {
  std::vector<cv::Mat> depth, confidence01, rgb, dynamic_mask;
  std::vector<PinholeCamera> cameras;
  std::vector<Rigid3d> world_from_cam;
};
Monst3rFolder Assemble(const std::string& name,
                       const std::string& tool,
                       Arrays arrays,
                       GridResize resize,
                       const std::string& units);

// `path` if it is a regular file named like `names` (exact or suffix
// match), else the first such file inside the folder `path`; nullopt if none.
std::optional<std::string> FindFile(const std::string& path,
                                    const std::vector<std::string>& suffixes);
// True when the npz at `path` has every key of `keys`.
bool NpzHasKeys(const std::string& path, const std::vector<std::string>& keys);

}  // namespace reconstruction
}  // namespace geodrive

namespace geodrive {
namespace reconstruction {
// One per file of geometry/reconstruction/.
std::unique_ptr<ReconstructionReader> CreateMonst3rReader();
std::unique_ptr<ReconstructionReader> CreateVggtReader();
std::unique_ptr<ReconstructionReader> CreateDepthAnything3Reader();
std::unique_ptr<ReconstructionReader> CreateCut3rReader();
std::unique_ptr<ReconstructionReader> CreateMegaSamReader();
std::unique_ptr<ReconstructionReader> CreateMogeReader();
std::unique_ptr<ReconstructionReader> CreateGenericNpzReader();
// Our GEN3C export's clip folder (gen3c_export.cc), read under the generic
// npz's name.
std::unique_ptr<ReconstructionReader> CreateGen3cExportReader();
// True when `path` (a folder, or its depth.npz) holds the GEN3C export's
// depth.npz, camera.npz and rgb.mp4 (names only: the generic npz reader hands
// such a folder to CreateGen3cExportReader, whose errors name what is wrong).
bool HasGen3cExportFiles(const std::string& path);
}  // namespace reconstruction
}  // namespace geodrive
