#pragma once
// nuScenes reader: the 13 tables of `<dataroot>/<version>/*.json`, the devkit's
// derived fields, a token index, per-channel sample_data chains, sensor world
// poses and annotation interpolation.
//
// Conventions (devkit `nuscenes.py`, see
// docs/reference/formats_monst3r_nuscenes.md section B):
//  - Quaternions in the JSON are [w, x, y, z] (parsed with QuaternionFromWxyz);
//  `size` is [w, l, h].
//  - Every sample_data (sweeps included) has its own ego_pose:
//    world_from_sensor = global_from_ego(that sample_data's ego_pose) *
//    ego_from_sensor.
//  - Records reference each other by row index (int32, kNoIndex = -1 for the
//  empty token "").
//
// Loading parses the JSON tables with simdjson in slices of whole records, on
// all threads (NuscenesOptions::num_threads), into compact structs (no DOM):
// v1.0-trainval-size metadata (2.6 M sample_data and ego_pose rows, 1.9 GB)
// loads in a few seconds within about 1.15 GB. The result and every error do
// not depend on the thread count. Every bad input throws InputError naming the
// table file and the record token.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <vector>

#include "geometry/camera.h"
#include "geometry/point_cloud.h"
#include "geometry/rigid3.h"

namespace geodrive {

constexpr int32_t kNoIndex = -1;

// A nuScenes token in 16 bytes. Lowercase 32-hex tokens are stored as their
// binary value; any other string (e.g. visibility tokens "1".."4") is interned
// in a process-wide table. The empty token "" is {0, 0}.
struct NuscenesToken {
  uint64_t hi = 0, lo = 0;
  bool empty() const { return hi == 0 && lo == 0; }
  bool operator==(const NuscenesToken& o) const {
    return hi == o.hi && lo == o.lo;
  }
  bool operator!=(const NuscenesToken& o) const { return !(*this == o); }
  bool operator<(const NuscenesToken& o) const {
    return hi != o.hi ? hi < o.hi : lo < o.lo;
  }
  // Parses (or interns) a token string.
  static NuscenesToken FromString(const std::string& text);
  std::string ToString() const;
};

enum class SensorModality { kCamera, kLidar, kRadar, kUnknown };
std::string ToString(SensorModality modality);

struct NuscenesCategory {
  NuscenesToken token;
  std::string name;  // e.g. "vehicle.car"
  std::string description;
  int index = -1;  // lidarseg index, -1 if absent
};

struct NuscenesAttribute {
  NuscenesToken token;
  std::string name;  // e.g. "vehicle.moving"
  std::string description;
};

struct NuscenesVisibility {
  NuscenesToken token;  // "1".."4"
  std::string level;    // e.g. "v80-100"
  std::string description;
};

struct NuscenesInstance {
  NuscenesToken token;
  int32_t category = kNoIndex;
  int nbr_annotations = 0;
  int32_t first_annotation = kNoIndex;
  int32_t last_annotation = kNoIndex;
};

struct NuscenesSensor {
  NuscenesToken token;
  std::string channel;  // e.g. "CAM_FRONT", "LIDAR_TOP"
  SensorModality modality = SensorModality::kUnknown;
};

struct NuscenesCalibratedSensor {
  NuscenesToken token;
  int32_t sensor = kNoIndex;
  Rigid3d
      ego_from_sensor;  // translation (m) + rotation (w, x, y, z) of the JSON
  bool has_intrinsic = false;
  Eigen::Matrix3d camera_intrinsic =
      Eigen::Matrix3d::Zero();  // row-major K; zero if absent
};

struct NuscenesEgoPose {
  NuscenesToken token;
  int64_t timestamp = 0;  // microseconds
  Rigid3d
      global_from_ego;  // translation (m) + rotation (w, x, y, z) of the JSON
};

struct NuscenesLog {
  NuscenesToken token;
  std::string logfile, vehicle, date_captured, location;
  int32_t map = kNoIndex;  // derived (devkit log['map_token'])
};

struct NuscenesScene {
  NuscenesToken token;
  std::string name;  // "scene-0001"
  std::string description;
  int32_t log = kNoIndex;
  int nbr_samples = 0;
  int32_t first_sample = kNoIndex;
  int32_t last_sample = kNoIndex;
};

struct NuscenesSample {
  NuscenesToken token;
  int64_t timestamp = 0;  // microseconds
  int32_t scene = kNoIndex;
  int32_t prev = kNoIndex, next = kNoIndex;
  // Derived (devkit sample['data']): keyframe sample_data per sensor row,
  // kNoIndex if none.
  std::vector<int32_t> data;
  // Derived (devkit sample['anns']): annotation rows, in table order.
  std::vector<int32_t> anns;
};

struct NuscenesSampleData {
  NuscenesToken token;
  int32_t sample = kNoIndex;  // for a sweep: the following keyframe
  int32_t ego_pose = kNoIndex;
  int32_t calibrated_sensor = kNoIndex;
  int32_t sensor =
      kNoIndex;  // derived: channel and modality via sensors()[sensor]
  int32_t prev = kNoIndex, next = kNoIndex;
  int64_t timestamp = 0;  // microseconds
  int32_t width = 0, height = 0;
  bool is_key_frame = false;
  std::string fileformat;  // "jpg", "pcd", ...
  std::string
      filename;  // relative to dataroot (validated: no "..", not absolute)
};

struct NuscenesSampleAnnotation {
  NuscenesToken token;
  int32_t sample = kNoIndex;
  int32_t instance = kNoIndex;
  int32_t visibility = kNoIndex;  // kNoIndex for ""
  int32_t category =
      kNoIndex;  // derived (devkit category_name via the instance)
  int32_t prev = kNoIndex, next = kNoIndex;
  std::vector<int32_t> attributes;
  Eigen::Vector3d translation =
      Eigen::Vector3d::Zero();  // box centre, global frame (m)
  Eigen::Vector3d size = Eigen::Vector3d::Zero();  // [w, l, h] (m)
  Eigen::Quaterniond rotation =
      Eigen::Quaterniond::Identity();  // global_from_box
  int num_lidar_pts = 0, num_radar_pts = 0;
};

struct NuscenesMap {
  NuscenesToken token;
  std::vector<int32_t> logs;
  std::string category;
  std::string filename;
};

// An oriented 3D box as the devkit's `Box`: centre, size [w, l, h], orientation
// (frame_from_box). Box frame: x forward (length), y left (width), z up
// (height). The frame is the caller's.
struct NuscenesBox {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  Eigen::Vector3d wlh = Eigen::Vector3d::Zero();
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
  int32_t annotation =
      kNoIndex;  // the sample_annotation row it came from (kNoIndex if none)
  int32_t instance = kNoIndex;
  int32_t category = kNoIndex;

  // The 8 corners in the devkit's order (Box.corners()): 0-3 the front face (x
  // = +l/2) with (y, z) = (+,+), (-,+), (-,-), (+,-); 4-7 the back face (x =
  // -l/2) with the same pattern.
  std::vector<Eigen::Vector3d> Corners(double wlh_factor = 1.0) const;
  // The same box in frame b, given b_from_a (a = this box's frame); like
  // Box.rotate/translate.
  NuscenesBox Transformed(const Rigid3d& b_from_a) const;
};

struct NuscenesOptions {
  std::string dataroot;  // folder holding <version>/ and samples/, sweeps/
  std::string version = "v1.0-mini";  // subfolder with the JSON tables
  // Quaternions must have |q| within this of 1 (and be finite); they are then
  // normalised.
  double quaternion_norm_tol = 1e-3;
  // Reject sample_data chains whose timestamps decrease.
  bool check_chain_order = true;
  // Threads that load the tables; 0 = OpenMP's default count
  // (OMP_NUM_THREADS), 1 = this thread only. The result (and any error) does
  // not depend on it.
  int num_threads = 0;
  void Check() const;
};

// Summary of a load: row counts and time.
struct NuscenesLoadSummary {
  double seconds = 0;
  size_t json_bytes = 0;
  // Optional tables absent from the version folder (attribute, visibility,
  // log, map): loaded as empty, references into them are kNoIndex.
  std::vector<std::string> missing_tables;
  std::string BriefReport() const;
};

class Nuscenes {
 public:
  // Loads and validates all tables; throws InputError on bad input.
  explicit Nuscenes(const NuscenesOptions& options);

  const NuscenesOptions& options() const { return options_; }
  const NuscenesLoadSummary& summary() const { return summary_; }
  std::string VersionDir() const;  // <dataroot>/<version>

  const std::vector<NuscenesCategory>& categories() const {
    return categories_;
  }
  const std::vector<NuscenesAttribute>& attributes() const {
    return attributes_;
  }
  const std::vector<NuscenesVisibility>& visibilities() const {
    return visibilities_;
  }
  const std::vector<NuscenesInstance>& instances() const { return instances_; }
  const std::vector<NuscenesSensor>& sensors() const { return sensors_; }
  const std::vector<NuscenesCalibratedSensor>& calibrated_sensors() const {
    return calibrated_sensors_;
  }
  const std::vector<NuscenesEgoPose>& ego_poses() const { return ego_poses_; }
  const std::vector<NuscenesLog>& logs() const { return logs_; }
  const std::vector<NuscenesScene>& scenes() const { return scenes_; }
  const std::vector<NuscenesSample>& samples() const { return samples_; }
  const std::vector<NuscenesSampleData>& sample_data() const {
    return sample_data_;
  }
  const std::vector<NuscenesSampleAnnotation>& sample_annotations() const {
    return sample_annotations_;
  }
  const std::vector<NuscenesMap>& maps() const { return maps_; }

  // Row of `token` in `table` ("sample_data", "scene", ... as the devkit names
  // them), or kNoIndex.
  int32_t Find(const std::string& table, const NuscenesToken& token) const;
  int32_t Find(const std::string& table, const std::string& token) const;
  // Sensor row of a channel name, or kNoIndex.
  int32_t FindSensor(const std::string& channel) const;
  int32_t FindScene(const std::string& name) const;

  // Derived fields of sample_data (devkit sd['channel'],
  // sd['sensor_modality']).
  const std::string& Channel(int32_t sample_data) const;
  SensorModality Modality(int32_t sample_data) const;
  // Derived annotation category name (devkit ann['category_name']).
  const std::string& CategoryName(int32_t annotation) const;

  // All sample_data of `channel` in `scene` (samples and sweeps), ordered along
  // the prev/next chain (by timestamp), without leaving the scene. Empty if the
  // scene has no such channel.
  const std::vector<int32_t>& Chain(int32_t scene, int32_t sensor) const;
  std::vector<int32_t> Chain(int32_t scene, const std::string& channel) const;

  // Poses of one sample_data, each with its own ego pose.
  Rigid3d GlobalFromEgo(int32_t sample_data) const;
  Rigid3d EgoFromSensor(int32_t sample_data) const;
  Rigid3d WorldFromSensor(
      int32_t sample_data) const;  // = GlobalFromEgo * EgoFromSensor
  // Camera intrinsics and size of a camera sample_data; throws InputError if it
  // has no 3x3 K.
  PinholeCamera Camera(int32_t sample_data) const;
  // <dataroot>/<filename>.
  std::string DataPath(int32_t sample_data) const;
  // Reads a LIDAR_TOP `.pcd.bin`; errors name the file and the sample_data
  // token.
  PointCloud LoadLidar(int32_t sample_data) const;

  // Boxes of one annotation in the global frame (devkit get_box).
  NuscenesBox GetBox(int32_t annotation) const;
  // Boxes of a sample_data in the global frame (devkit get_boxes): the sample's
  // annotations for a keyframe; for a sweep, centre lerp and rotation slerp
  // between the previous sample and the sample it points to (t clamped to [t0,
  // t1]); instances absent from the previous sample keep their current box.
  std::vector<NuscenesBox> GetBoxes(int32_t sample_data) const;

 private:
  struct LoadState;
  void Load();
  void AddDescriptionTables(LoadState* state);
  void AddCaptureTables(LoadState* state);
  void BuildTokenIndices(const LoadState* state);
  void BuildTokenIndex(int table, const std::string& path);
  size_t TableRowCount(int table) const;
  const NuscenesToken& RowToken(int table, int32_t row) const;
  int32_t FindRow(int table, const NuscenesToken& token) const;
  // FindRow, trying rows near + 1 and near first (a record that references
  // the row after, or the same row as, the previous record's reference):
  // the same answer, without a hash probe when the guess is right.
  int32_t FindRowNear(int table,
                      const NuscenesToken& token,
                      int32_t near) const;
  void PrefetchRefs(const std::vector<NuscenesToken>& refs,
                    const int* targets,
                    int per_row,
                    size_t row) const;
  void Resolve(LoadState* state);
  int32_t ResolveRef(const LoadState& state,
                     int table,
                     const NuscenesToken& self,
                     const char* field,
                     int target,
                     const NuscenesToken& ref,
                     bool required,
                     int32_t near = kNoIndex) const;
  template <typename Row>
  void ResolveNextAndGuessPrev(int table,
                               const std::vector<NuscenesToken>& refs,
                               int threads,
                               std::vector<Row>* rows) const;
  void ResolveSampleData(LoadState* state, int threads);
  void ResolveAnnotations(LoadState* state, int threads);
  void BuildChains();

  NuscenesOptions options_;
  NuscenesLoadSummary summary_;
  std::vector<NuscenesCategory> categories_;
  std::vector<NuscenesAttribute> attributes_;
  std::vector<NuscenesVisibility> visibilities_;
  std::vector<NuscenesInstance> instances_;
  std::vector<NuscenesSensor> sensors_;
  std::vector<NuscenesCalibratedSensor> calibrated_sensors_;
  std::vector<NuscenesEgoPose> ego_poses_;
  std::vector<NuscenesLog> logs_;
  std::vector<NuscenesScene> scenes_;
  std::vector<NuscenesSample> samples_;
  std::vector<NuscenesSampleData> sample_data_;
  std::vector<NuscenesSampleAnnotation> sample_annotations_;
  std::vector<NuscenesMap> maps_;

  // Open-addressing token -> row index per table (slot arrays of row indices).
  struct TokenIndex {
    std::vector<int32_t> slots;
    uint64_t mask = 0;
  };
  TokenIndex index_[13];
  // chains_[scene * sensors + sensor].
  std::vector<std::vector<int32_t>> chains_;
};

}  // namespace geodrive
