// nuScenes reader on a small fixture with closed-form truth: tables, derived
// fields, token index, chains, poses, interpolation, and one test per kind of
// bad input.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>

#include "dataset/nuscenes.h"
#include "geometry/util/status.h"
#include "tests/common/test_util.h"
#include "tests/dataset/nuscenes_fixture.h"

namespace geodrive {
namespace nuscenes_tables_test {
namespace {

using test::NuscenesFixture;
using json = nlohmann::json;
using ::testing::AllOf;
using ::testing::HasSubstr;

NuscenesOptions Options(const std::string& root) {
  NuscenesOptions options;
  options.dataroot = root;
  options.version = "v1.0-mini";
  return options;
}

TEST(NuscenesToken, HexRoundTripAndInterning) {
  const std::string hex = "e3d495d4ac534d54b321f50006683844";
  const NuscenesToken t = NuscenesToken::FromString(hex);
  EXPECT_EQ(t.ToString(), hex);
  EXPECT_FALSE(t.empty());
  EXPECT_TRUE(NuscenesToken::FromString("").empty());
  const NuscenesToken v = NuscenesToken::FromString("4");
  EXPECT_EQ(v.ToString(), "4");
  EXPECT_EQ(v, NuscenesToken::FromString("4"));
  EXPECT_NE(v, NuscenesToken::FromString("3"));
  // Upper-case hex is a different token string: interned, round-trips
  // unchanged.
  EXPECT_EQ(
      NuscenesToken::FromString("E3D495D4AC534D54B321F50006683844").ToString(),
      "E3D495D4AC534D54B321F50006683844");
}

TEST(Nuscenes, LoadsTablesAndDerivedFields) {
  NuscenesFixture fx;
  const std::string root = fx.Write(test::MakeTempDir("nusc_tables_load"));
  const Nuscenes nusc(Options(root));
  EXPECT_EQ(nusc.scenes().size(), 2u);
  EXPECT_EQ(nusc.samples().size(), 20u);
  EXPECT_EQ(nusc.sample_data().size(), fx.tables["sample_data"].size());
  EXPECT_EQ(nusc.ego_poses().size(), fx.tables["ego_pose"].size());
  EXPECT_EQ(nusc.sample_annotations().size(),
            fx.tables["sample_annotation"].size());
  EXPECT_EQ(nusc.visibilities().size(), 4u);
  EXPECT_EQ(nusc.maps().size(), 1u);
  // log.map_token.
  EXPECT_EQ(nusc.logs()[0].map, 0);
  // Every sample has a keyframe per channel; sample.data points back at
  // keyframes of the sample.
  const int32_t cam = nusc.FindSensor("CAM_FRONT"),
                lidar = nusc.FindSensor("LIDAR_TOP");
  ASSERT_NE(cam, kNoIndex);
  ASSERT_NE(lidar, kNoIndex);
  for (size_t s = 0; s < nusc.samples().size(); ++s) {
    for (int32_t sensor : {cam, lidar}) {
      const int32_t sd = nusc.samples()[s].data[sensor];
      ASSERT_NE(sd, kNoIndex);
      EXPECT_TRUE(nusc.sample_data()[sd].is_key_frame);
      EXPECT_EQ(nusc.sample_data()[sd].sample, static_cast<int32_t>(s));
    }
  }
  // Channel / modality and category name.
  const json& first_sd = fx.tables["sample_data"][0];
  const int32_t sd0 =
      nusc.Find("sample_data", first_sd["token"].get<std::string>());
  ASSERT_EQ(sd0, 0);
  EXPECT_EQ(nusc.Channel(sd0), "CAM_FRONT");
  EXPECT_EQ(nusc.Modality(sd0), SensorModality::kCamera);
  EXPECT_EQ(nusc.CategoryName(0), "vehicle.car");
  EXPECT_EQ(nusc.sample_annotations()[0].visibility,
            nusc.Find("visibility", std::string("4")));
  EXPECT_EQ(nusc.sample_data()[sd0].token.ToString(),
            first_sd["token"].get<std::string>());
  // Annotations per sample: instance 0 always, instance 1 from sample 3.
  EXPECT_EQ(nusc.samples()[0].anns.size(), 1u);
  EXPECT_EQ(nusc.samples()[5].anns.size(), 2u);
  EXPECT_EQ(
      nusc.Find("sample_data", std::string("00000000000000000000000000000001")),
      kNoIndex);
  EXPECT_THROW(nusc.Find("no_such_table", std::string("x")), InputError);
}

TEST(Nuscenes, ChainsAreOrderedStayInSceneAndHaveTheSensorRates) {
  NuscenesFixture fx;
  const Nuscenes nusc(
      Options(fx.Write(test::MakeTempDir("nusc_tables_chain"))));
  for (int32_t scene = 0; scene < 2; ++scene) {
    const auto cam = nusc.Chain(scene, "CAM_FRONT");
    const auto lidar = nusc.Chain(scene, "LIDAR_TOP");
    EXPECT_EQ(cam.size(), 9u * 6 + 1);
    EXPECT_EQ(lidar.size(), 9u * 10 + 1);
    for (const auto* chain : {&cam, &lidar}) {
      const double period = chain == &cam ? 1e6 / 12 : 1e6 / 20;
      for (size_t i = 1; i < chain->size(); ++i) {
        const auto& a = nusc.sample_data()[(*chain)[i - 1]];
        const auto& b = nusc.sample_data()[(*chain)[i]];
        EXPECT_NEAR(static_cast<double>(b.timestamp - a.timestamp), period,
                    1000.0);
        EXPECT_EQ(nusc.samples()[b.sample].scene, scene);
        EXPECT_EQ(b.prev, (*chain)[i - 1]);
      }
    }
  }
  EXPECT_TRUE(nusc.Chain(0, "CAM_BACK").empty());
}

// world_from_cam = global_from_ego(own ego pose) * ego_from_cam, checked
// against the fixture's closed-form ego motion at each frame's own timestamp.
TEST(Nuscenes, WorldFromSensorUsesEachSampleDataOwnEgoPose) {
  NuscenesFixture fx;
  const Nuscenes nusc(Options(fx.Write(test::MakeTempDir("nusc_tables_pose"))));
  const auto chain = nusc.Chain(1, "CAM_FRONT");
  const int64_t t0 = nusc.sample_data()[chain[0]].timestamp;
  const Rigid3d ego_from_cam = nusc.calibrated_sensors()[0].ego_from_sensor;
  for (int32_t sd : chain) {
    const double t = (nusc.sample_data()[sd].timestamp - t0) * 1e-6;
    const Rigid3d global_from_ego(
        Eigen::Quaterniond(Eigen::AngleAxisd(NuscenesFixture::kYawRate * t,
                                             Eigen::Vector3d::UnitZ())),
        Eigen::Vector3d(NuscenesFixture::kSpeed * t, 0, 0));
    const Eigen::Matrix4d expected =
        global_from_ego.ToMatrix() * ego_from_cam.ToMatrix();
    EXPECT_THAT(nusc.WorldFromSensor(sd).ToMatrix(),
                test::EigenNear(expected, 1e-9));
  }
  const PinholeCamera camera = nusc.Camera(chain[0]);
  EXPECT_EQ(camera.width, NuscenesFixture::kWidth);
  EXPECT_DOUBLE_EQ(camera.fx, 126.0);
  EXPECT_THROW(nusc.Camera(nusc.Chain(0, "LIDAR_TOP")[0]), InputError);
}

// Sweeps get boxes interpolated between the previous sample and the sample they
// point to; the fixture's motion is linear in centre and yaw, so lerp/slerp
// reproduce the truth exactly.
TEST(Nuscenes, SweepBoxesAreInterpolatedAsGetBoxes) {
  NuscenesFixture fx;
  const Nuscenes nusc(
      Options(fx.Write(test::MakeTempDir("nusc_tables_interp"))));
  const auto chain = nusc.Chain(0, "CAM_FRONT");
  const int64_t t0 = nusc.sample_data()[chain[0]].timestamp;
  int checked = 0;
  for (int32_t sd : chain) {
    const auto& d = nusc.sample_data()[sd];
    const double t = (d.timestamp - t0) * 1e-6;
    const auto& sample = nusc.samples()[d.sample];
    const int sample_index = static_cast<int>((sample.timestamp - t0) / 500000);
    for (const NuscenesBox& box : nusc.GetBoxes(sd)) {
      const int k =
          box.instance == nusc.sample_annotations()[0].instance ? 0 : 1;
      // Keyframes, the first sample and instances absent from the previous
      // sample (instance 1 before sample 4) keep the sample's own box; the rest
      // are interpolated at t.
      const bool interpolated = !d.is_key_frame && sample.prev != kNoIndex &&
                                (k == 0 || sample_index >= 4);
      const double t_box = interpolated ? t : 0.5 * sample_index;
      EXPECT_THAT(box.center,
                  test::EigenNear(NuscenesFixture::CarCenter(k, t_box), 1e-9));
      const double yaw = NuscenesFixture::CarYaw(k, t_box);
      const Eigen::Quaterniond q(
          Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()));
      EXPECT_LT(q.angularDistance(box.orientation), 1e-9);
      EXPECT_THAT(box.wlh, test::EigenNear(Eigen::Vector3d(1.9, 4.5, 1.6), 0));
      ++checked;
    }
  }
  EXPECT_GT(checked, 80);
}

TEST(NuscenesBox, CornersFollowTheDevkitOrder) {
  NuscenesBox box;
  box.center = Eigen::Vector3d(1, 2, 3);
  box.wlh = Eigen::Vector3d(2, 4, 6);  // w, l, h
  const auto c = box.Corners();
  ASSERT_EQ(c.size(), 8u);
  // Devkit: x = l/2 * [1,1,1,1,-1,-1,-1,-1], y = w/2 * [1,-1,-1,1,1,-1,-1,1],
  // z = h/2 * [1,1,-1,-1,1,1,-1,-1].
  const double xs[8] = {2, 2, 2, 2, -2, -2, -2, -2},
               ys[8] = {1, -1, -1, 1, 1, -1, -1, 1},
               zs[8] = {3, 3, -3, -3, 3, 3, -3, -3};
  for (int i = 0; i < 8; ++i) {
    EXPECT_THAT(
        c[i], test::EigenNear(Eigen::Vector3d(1 + xs[i], 2 + ys[i], 3 + zs[i]),
                              1e-12));
  }
  // Rotated 90 degrees about z: the front face moves to +y.
  box.orientation =
      Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()));
  EXPECT_THAT(box.Corners()[0],
              test::EigenNear(Eigen::Vector3d(1 - 1, 2 + 2, 6), 1e-12));
}

// ---- Bad input: one error naming the table file (and the record token).

class NuscenesBadInput : public ::testing::Test {
 protected:
  std::string Load(const std::string& name) {
    root_ = fx_.Write(test::MakeTempDir("nusc_bad_" + name));
    try {
      Nuscenes nusc(Options(root_));
    } catch (const InputError& e) {
      const std::string what = e.what();
      EXPECT_EQ(what.find('\n'), std::string::npos) << what;
      return what;
    }
    ADD_FAILURE() << "no InputError for " << name;
    return "";
  }
  std::string Tok(const char* table, int row) {
    return fx_.tables[table][row]["token"].get<std::string>();
  }
  NuscenesFixture fx_;
  std::string root_;
};

TEST_F(NuscenesBadInput, MissingTableFile) {
  fx_.Write(test::MakeTempDir("nusc_bad_missing"));
  std::filesystem::remove(test::MakeTempDir("nusc_bad_missing") +
                          "/x");  // keep dir fresh
  const std::string root = fx_.Write(test::MakeTempDir("nusc_bad_missing"));
  std::filesystem::remove(root + "/v1.0-mini/sample_annotation.json");
  try {
    Nuscenes nusc(Options(root));
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), AllOf(HasSubstr("sample_annotation.json"),
                                HasSubstr("missing table")));
  }
}

// Real extracts lack attribute, visibility, log and map: the dataset loads,
// names what is missing once, and references into those tables are unknown.
TEST_F(NuscenesBadInput, OptionalTablesMayBeMissing) {
  const std::string root =
      fx_.Write(test::MakeTempDir("nusc_optional_missing"));
  for (const char* t : {"attribute", "visibility", "log", "map"})
    std::filesystem::remove(root + "/v1.0-mini/" + t + ".json");
  const Nuscenes nusc(Options(root));
  EXPECT_THAT(nusc.summary().missing_tables,
              ::testing::ElementsAre("attribute", "visibility", "log", "map"));
  EXPECT_THAT(nusc.summary().BriefReport(),
              HasSubstr("optional tables missing (references to them are "
                        "unknown): attribute visibility log map"));
  EXPECT_TRUE(nusc.logs().empty());
  ASSERT_FALSE(nusc.sample_annotations().empty());
  for (const auto& a : nusc.sample_annotations()) {
    EXPECT_EQ(a.visibility, kNoIndex);
    EXPECT_TRUE(a.attributes.empty());
  }
  for (const auto& s : nusc.scenes()) EXPECT_EQ(s.log, kNoIndex);
  // Everything else still resolves: boxes, poses, cameras.
  EXPECT_FALSE(nusc.samples().empty());
  EXPECT_EQ(nusc.sample_annotations().size(),
            Nuscenes(Options(fx_.Write(test::MakeTempDir("nusc_optional_all"))))
                .sample_annotations()
                .size());
}

TEST_F(NuscenesBadInput, TruncatedJson) {
  const std::string root = fx_.Write(test::MakeTempDir("nusc_bad_truncated"));
  const std::string path = root + "/v1.0-mini/sample_data.json";
  const auto size = std::filesystem::file_size(path);
  std::filesystem::resize_file(path, size / 2);
  try {
    Nuscenes nusc(Options(root));
    FAIL() << "no error";
  } catch (const InputError& e) {
    // Truncated mid-file: the error names the file and the record being read.
    EXPECT_THAT(e.what(),
                AllOf(HasSubstr("sample_data.json"),
                      HasSubstr("malformed JSON"), HasSubstr("record ")));
  }
}

TEST_F(NuscenesBadInput, PythonNanLiteralIsMalformedJsonNamingTheRecord) {
  const std::string root = fx_.Write(test::MakeTempDir("nusc_bad_nanliteral"));
  const std::string path = root + "/v1.0-mini/ego_pose.json";
  std::string text;
  {
    std::ifstream in(path);
    text.assign(std::istreambuf_iterator<char>(in), {});
  }
  const std::string tok = Tok("ego_pose", 3);
  const size_t at = text.find("\"rotation\"", text.find(tok));
  text.replace(text.find('[', at) + 1, 0,
               "NaN,");  // what Python's json.dump writes for nan
  std::ofstream(path) << text;
  try {
    Nuscenes nusc(Options(root));
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), AllOf(HasSubstr("ego_pose.json"), HasSubstr(tok)));
  }
}

TEST_F(NuscenesBadInput, UnresolvedTokenReference) {
  fx_.tables["sample_data"][7]["ego_pose_token"] =
      "0123456789abcdef0123456789abcdef";
  EXPECT_THAT(
      Load("unresolved"),
      AllOf(HasSubstr("sample_data.json"), HasSubstr(Tok("sample_data", 7)),
            HasSubstr("ego_pose_token 0123456789abcdef0123456789abcdef does "
                      "not resolve")));
}

TEST_F(NuscenesBadInput, NonUnitQuaternion) {
  fx_.tables["ego_pose"][4]["rotation"] = {2.0, 0.0, 0.0, 0.0};
  EXPECT_THAT(Load("nonunit"),
              AllOf(HasSubstr("ego_pose.json"), HasSubstr(Tok("ego_pose", 4)),
                    HasSubstr("not unit")));
}

TEST_F(NuscenesBadInput, NanQuaternion) {
  // nlohmann (and many writers) store NaN as null.
  fx_.tables["calibrated_sensor"][0]["rotation"] = {std::nan(""), 0.0, 0.0,
                                                    1.0};
  EXPECT_THAT(Load("nanquat"), AllOf(HasSubstr("calibrated_sensor.json"),
                                     HasSubstr(Tok("calibrated_sensor", 0)),
                                     HasSubstr("rotation")));
  fx_.tables["calibrated_sensor"][0]["rotation"] = {1e308 * 10, 0.0, 0.0, 1.0};
  EXPECT_THAT(Load("infquat"), AllOf(HasSubstr("calibrated_sensor.json"),
                                     HasSubstr(Tok("calibrated_sensor", 0)),
                                     HasSubstr("rotation")));
}

// Found by fuzz_nuscenes_tables (UBSan): an integral double beyond int64
// (1.7e93) was cast to int64_t, which is undefined.
TEST_F(NuscenesBadInput, TimestampBeyondInt64IsAnError) {
  fx_.tables["ego_pose"][4]["timestamp"] = 1.7e93;
  EXPECT_THAT(Load("hugets"),
              AllOf(HasSubstr("ego_pose.json"), HasSubstr(Tok("ego_pose", 4)),
                    HasSubstr("not an integer in the int64 range")));
}

TEST_F(NuscenesBadInput, IntrinsicNot3x3) {
  fx_.tables["calibrated_sensor"][0]["camera_intrinsic"] = {{126.0, 0.0, 80.0},
                                                            {0.0, 126.0, 45.0}};
  EXPECT_THAT(Load("intrinsic"), AllOf(HasSubstr("calibrated_sensor.json"),
                                       HasSubstr(Tok("calibrated_sensor", 0)),
                                       HasSubstr("not 3x3")));
  fx_.tables["calibrated_sensor"][0]["camera_intrinsic"] = {1.0, 2.0, 3.0};
  EXPECT_THAT(Load("intrinsic_flat"),
              AllOf(HasSubstr(Tok("calibrated_sensor", 0)), HasSubstr("3x3")));
}

TEST_F(NuscenesBadInput, FilenameOutsideTheDataset) {
  fx_.tables["sample_data"][2]["filename"] = "samples/../../etc/passwd";
  EXPECT_THAT(Load("dotdot"),
              AllOf(HasSubstr("sample_data.json"),
                    HasSubstr(Tok("sample_data", 2)), HasSubstr("'..'")));
  fx_.tables["sample_data"][2]["filename"] = "/etc/passwd";
  EXPECT_THAT(Load("absolute"), AllOf(HasSubstr("sample_data.json"),
                                      HasSubstr(Tok("sample_data", 2)),
                                      HasSubstr("absolute path")));
}

// A prev/next chain that forks (a next that skips a record, so the record
// would silently drop out of every clip) is refused, naming the records.
TEST_F(NuscenesBadInput, ForkedChainNamesTheRecords) {
  auto& sd = fx_.tables["sample_data"];
  std::map<std::string, size_t> row_of;
  for (size_t i = 0; i < sd.size(); ++i)
    row_of[sd[i]["token"].get<std::string>()] = i;
  for (size_t i = 0; i < sd.size(); ++i) {
    const std::string n1 = sd[i]["next"].get<std::string>();
    if (n1.empty()) continue;
    const std::string n2 = sd[row_of[n1]]["next"].get<std::string>();
    if (n2.empty()) continue;
    sd[i]["next"] = n2;  // skips n1, whose prev still names row i
    EXPECT_THAT(Load("fork"), AllOf(HasSubstr("sample_data.json"),
                                    HasSubstr(n2), HasSubstr("forks")));
    return;
  }
  FAIL() << "the fixture has no chain of three records";
}

TEST_F(NuscenesBadInput, DuplicateToken) {
  fx_.tables["ego_pose"][5]["token"] = Tok("ego_pose", 6);
  EXPECT_THAT(Load("duplicate"),
              AllOf(HasSubstr("ego_pose.json"), HasSubstr(Tok("ego_pose", 6)),
                    HasSubstr("duplicate")));
}

TEST_F(NuscenesBadInput, LidarFileSizeNotMultipleOf20) {
  const std::string root = fx_.Write(test::MakeTempDir("nusc_bad_pcdbin"));
  const Nuscenes nusc(Options(root));
  const int32_t sd = nusc.Chain(0, "LIDAR_TOP")[0];
  const std::string path = nusc.DataPath(sd);
  std::filesystem::create_directories(
      std::filesystem::path(path).parent_path());
  std::ofstream(path, std::ios::binary) << std::string(41, '\0');
  try {
    nusc.LoadLidar(sd);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(),
                AllOf(HasSubstr(path),
                      HasSubstr(nusc.sample_data()[sd].token.ToString())));
  }
  // A valid file loads.
  std::ofstream(path, std::ios::binary) << std::string(40, '\0');
  EXPECT_EQ(nusc.LoadLidar(sd).size(), 2u);
}

}  // namespace
}  // namespace nuscenes_tables_test
}  // namespace geodrive
