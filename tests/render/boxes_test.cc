#include "render/boxes.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <string>

#include "geometry/util/status.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace {

BoxSequences SampleBoxes() {
  BoxSequences boxes;
  boxes.image_width = 1600;
  boxes.image_height = 900;
  boxes.num_frames = 25;
  boxes.units = "metres";
  BoxSequence a;
  a.id = "4f1a-token";
  a.category = "vehicle.car";
  for (int f : {0, 1, 2, 5, 24}) {
    BoxFrame bf;
    bf.frame = f;
    bf.box_2d = Box2d{100.25 + f, 200.5, 300.75 + f, 400.125};
    Box3d b;
    b.center = Eigen::Vector3d(10.0 + 0.1 * f, -3.25, 0.8);
    b.size = Eigen::Vector3d(1.9, 4.5, 1.6);
    b.rotation = QuaternionFromAngleAxis(Eigen::Vector3d(0, 0, 0.3 + 0.01 * f));
    bf.box_3d = b;
    bf.visibility = 0.75;
    a.frames.push_back(bf);
  }
  BoxSequence b;
  b.id = "user-edit";
  BoxFrame only2d;
  only2d.frame = 3;
  only2d.box_2d = Box2d{0, 0, 10, 10};
  b.frames.push_back(only2d);
  boxes.instances = {a, b};
  return boxes;
}

void WriteText(const std::string& path, const std::string& text) {
  std::ofstream out(path);
  out << text;
}

std::string ErrorOf(const std::string& path) {
  try {
    ReadBoxesJson(path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(Boxes, WriteReadRoundTripIsExact) {
  const std::string dir = test::MakeTempDir("boxes_roundtrip");
  const BoxSequences boxes = SampleBoxes();
  WriteBoxesJson(dir + "/boxes.json", boxes);
  const BoxSequences back = ReadBoxesJson(dir + "/boxes.json");
  ASSERT_EQ(back.instances.size(), 2u);
  EXPECT_EQ(back.image_width, 1600);
  EXPECT_EQ(back.image_height, 900);
  EXPECT_EQ(back.num_frames, 25);
  EXPECT_EQ(back.units, "metres");
  const BoxSequence& a = back.instances[0];
  EXPECT_EQ(a.id, "4f1a-token");
  EXPECT_EQ(a.category, "vehicle.car");
  ASSERT_EQ(a.frames.size(), 5u);
  for (size_t k = 0; k < a.frames.size(); ++k) {
    const BoxFrame& x = boxes.instances[0].frames[k];
    const BoxFrame& y = a.frames[k];
    EXPECT_EQ(x.frame, y.frame);
    // JSON numbers are written with round-trip precision: exact.
    EXPECT_EQ(x.box_2d->xmin, y.box_2d->xmin);
    EXPECT_EQ(x.box_2d->ymax, y.box_2d->ymax);
    EXPECT_EQ(x.box_3d->center, y.box_3d->center);
    EXPECT_EQ(x.box_3d->size, y.box_3d->size);
    EXPECT_LT(RotationDistanceDeg(x.box_3d->rotation, y.box_3d->rotation),
              1e-9);
    EXPECT_EQ(*y.visibility, 0.75);
  }
  EXPECT_FALSE(back.instances[1].frames[0].box_3d.has_value());
  EXPECT_EQ(back.instances[1].Find(3)->box_2d->xmax, 10.0);
  EXPECT_EQ(back.instances[1].Find(4), nullptr);
}

TEST(Boxes, WrittenFileValidatesAgainstSchema) {
  GEODRIVE_REQUIRE_PYTHON_MODULE("jsonschema");
  const std::string dir = test::MakeTempDir("boxes_schema");
  WriteBoxesJson(dir + "/boxes.json", SampleBoxes());
  const std::string py = std::string(test::kDebianPython) +
                         " " GEODRIVE_SOURCE_DIR
                         "/tests/dataset/validate_json.py " GEODRIVE_SOURCE_DIR
                         "/data_schema/boxes.schema.json ";
  std::string out;
  EXPECT_EQ(test::RunCommand(py + dir + "/boxes.json", &out), 0) << out;
  // The schema is not vacuous: a box_2d with 3 numbers and a missing "frame"
  // are rejected.
  WriteText(
      dir + "/bad.json",
      R"({"format": "geodrive-boxes", "version": 1, "image_width": 10, "image_height": 10,
                "num_frames": 2, "instances": [{"id": "a", "frames": [{"box_2d": [1, 2, 3]}]}]})");
  EXPECT_NE(test::RunCommand(py + dir + "/bad.json", &out), 0) << out;
}

// Found by fuzzing the trajectory reader, which shares the pattern: a
// non-string "format" must be an InputError, not nlohmann's type_error.
TEST(Boxes, NonStringFormatIsAnInputError) {
  const std::string path = test::MakeTempDir("boxes_format") + "/b.json";
  std::ofstream(path) << R"({"format": ["geodrive-boxes"], "version": 1})";
  try {
    ReadBoxesJson(path);
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), path + ": \"format\" must be a string");
  }
}

TEST(Boxes, MalformedFilesGiveOneClearError) {
  const std::string dir = test::MakeTempDir("boxes_bad");
  const std::string head =
      R"({"format": "geodrive-boxes", "version": 1, "image_width": 1600, "image_height": 900,
          "num_frames": 25, "instances": )";
  struct Case {
    std::string body, expect;
  };
  const Case cases[] = {
      {"[{\"id\": \"a\", \"frames\": [{\"frame\": 0, \"box_2d\": [1, 2, "
       "3]}]}]}",
       "instances[0].frames[0].box_2d must be an array of 4 numbers"},
      {"[{\"id\": \"a\", \"frames\": [{\"frame\": 0, \"box_2d\": [30, 2, 10, "
       "40]}]}]}",
       "is inverted"},
      {"[{\"id\": \"a\", \"frames\": [{\"frame\": 25, \"box_2d\": [1, 2, 3, "
       "4]}]}]}",
       "frame index outside 0..24"},
      {"[{\"id\": \"a\", \"frames\": [{\"frame\": 3, \"box_2d\": [1, 2, 3, "
       "4]}, "
       "{\"frame\": 3, \"box_2d\": [1, 2, 3, 4]}]}]}",
       "listed once each in increasing order"},
      {"[{\"id\": \"a\", \"frames\": [{\"frame\": 0}]}]}",
       "needs box_2d or box_3d"},
      {"[{\"id\": \"a\", \"frames\": [{\"frame\": 0, \"box_3d\": {\"center\": "
       "[0, 0, 0], "
       "\"size\": [1, 1, 1], \"rotation_wxyz\": [2, 0, 0, 0]}}]}]}",
       "rotation_wxyz has norm 2"},
      {"[{\"id\": \"a\", \"frames\": [{\"frame\": 0, \"box_3d\": {\"center\": "
       "[0, 0, 0], "
       "\"size\": [1, 0, 1], \"rotation_wxyz\": [1, 0, 0, 0]}}]}]}",
       "size > 0"},
      {"[{\"id\": \"a\", \"frames\": [{\"frame\": 0, \"bbox\": [1, 2, 3, "
       "4]}]}]}",
       "unknown key \"bbox\""},
      {"[{\"id\": \"a\", \"frames\": []}, {\"id\": \"a\", \"frames\": []}]}",
       "duplicate instance id"},
      {"[{\"id\": \"a\", \"frames\": [{\"frame\": 0, \"box_2d\": [1, 2, 3, 4], "
       "\"visibility\": 1.5}]}]}",
       "visibility 1.5 must be in [0, 1]"},
      {"[{\"id\": \"a\", \"frames\": [{\"frame\": 0, \"box_2d\": [1, 2, 3, "
       "4]}]}",
       "malformed JSON"},
  };
  int k = 0;
  for (const Case& c : cases) {
    const std::string path = dir + "/bad" + std::to_string(k++) + ".json";
    WriteText(path, head + c.body);
    const std::string error = ErrorOf(path);
    EXPECT_NE(error.find(path), std::string::npos) << error;
    EXPECT_NE(error.find(c.expect), std::string::npos) << "got: " << error;
    EXPECT_EQ(error.find('\n'), std::string::npos) << "one line: " << error;
  }
  EXPECT_NE(ErrorOf(dir + "/missing.json").find("cannot open"),
            std::string::npos);
  WriteText(dir + "/fmt.json", R"({"format": "other", "version": 1})");
  EXPECT_NE(ErrorOf(dir + "/fmt.json").find("\"format\" must be"),
            std::string::npos);
}

TEST(Boxes, Box3dGeometryFollowsNuscenesConvention) {
  // Yaw 90 deg: the box's x (length) axis points along world +y.
  Box3d b;
  b.center = Eigen::Vector3d(10, 2, 0.8);
  b.size = Eigen::Vector3d(2.0, 4.0, 1.6);  // w, l, h
  b.rotation = QuaternionFromWxyz(std::cos(M_PI / 4), 0, 0, std::sin(M_PI / 4));
  EXPECT_TRUE(
      b.Contains(Eigen::Vector3d(10, 3.9, 0.8)));  // 1.9 along the length
  EXPECT_FALSE(b.Contains(
      Eigen::Vector3d(11.1, 2, 0.8)));  // 1.1 along the width (half = 1)
  EXPECT_TRUE(b.Contains(Eigen::Vector3d(11.1, 2, 0.8), 0.11));
  for (const Eigen::Vector3d& c : b.Corners()) {
    EXPECT_NEAR(std::abs(c.x() - 10), 1.0, 1e-12);
    EXPECT_NEAR(std::abs(c.y() - 2), 2.0, 1e-12);
    EXPECT_NEAR(std::abs(c.z() - 0.8), 0.8, 1e-12);
  }
  // Projection: min/max of the corners projected by hand.
  const PinholeCamera cam(500, 500, 320, 240, 640, 480);
  Eigen::Matrix3d r;  // camera looking along world +x, z up
  r << 0, -1, 0, 0, 0, -1, 1, 0, 0;
  const Rigid3d cam_from_world(Eigen::Quaterniond(r),
                               Eigen::Vector3d(0, 1.5, 0));
  const std::optional<Box2d> p = ProjectBox3d(b, cam, cam_from_world);
  ASSERT_TRUE(p.has_value());
  double xmin = 1e9, xmax = -1e9;
  for (const Eigen::Vector3d& c : b.Corners()) {
    const Eigen::Vector3d q = cam_from_world * c;
    xmin = std::min(xmin, 500 * q.x() / q.z() + 320);
    xmax = std::max(xmax, 500 * q.x() / q.z() + 320);
  }
  EXPECT_DOUBLE_EQ(p->xmin, xmin);
  EXPECT_DOUBLE_EQ(p->xmax, xmax);
  // Entirely behind the camera: nothing.
  Box3d behind = b;
  behind.center.x() = -10;
  EXPECT_FALSE(ProjectBox3d(behind, cam, cam_from_world).has_value());
  // Interpolation halfway: centre midpoint, yaw midpoint.
  Box3d b2 = b;
  b2.center.x() = 12;
  b2.rotation = QuaternionFromAngleAxis(Eigen::Vector3d(0, 0, M_PI / 2 + 0.2));
  const Box3d mid = Interpolate(b, b2, 0.5);
  EXPECT_NEAR(mid.center.x(), 11, 1e-12);
  EXPECT_NEAR(QuaternionToAngleAxis(mid.rotation).z(), M_PI / 2 + 0.1, 1e-9);
}

TEST(Boxes, Box2dAreaClipAndScale) {
  const Box2d b{-10, 5, 30, 25};
  EXPECT_DOUBLE_EQ(b.Area(), 800);
  EXPECT_DOUBLE_EQ(b.Clipped(20, 20).Area(), 20 * 15);
  EXPECT_DOUBLE_EQ((Box2d{5, 5, 5, 9}).Area(), 0);  // zero width
  EXPECT_DOUBLE_EQ((Box2d{30, 30, 40, 40}).Clipped(20, 20).Area(),
                   0);                   // outside
  const Box2d s = b.Scaled(0.32, 0.32);  // 1600x900 -> 512x288
  EXPECT_DOUBLE_EQ(s.xmax, 9.6);
  EXPECT_FALSE((Box2d{3, 0, 1, 1}).IsOrdered());
}

}  // namespace
}  // namespace geodrive
