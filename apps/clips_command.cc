// `geodrive clips`: which frames make each clip, as files a reconstruction
// tool can run on. Per clip OUT/<clip_id>/clip.json (clip id, scene, frame
// files, timestamps, sample_data tokens, intrinsics, ego poses) and
// OUT/<clip_id>/images/00000.jpg ... (links to the dataset's images, named as
// MonST3R's demo expects: sorted file names), plus OUT/clips.jsonl, one line
// per clip with its index (the upstream `sample_%06d` number). A clip whose
// images are missing on disk is listed in OUT/failures.jsonl and skipped.

#include <algorithm>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>

#include "apps/cli/cli.h"
#include "dataset/drive_dataset.h"
#include "dataset/pairs.h"
#include "geometry/image_io.h"
#include "geometry/util/files.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

struct ClipsArgs {
  DriveDatasetOptions dataset;
  std::string format = "auto";  // --dataset
  std::string frames = "all";
  std::string out;
  std::string clips;  // comma-separated ids; empty = all
  bool copy = false;
};

json Matrix(const Rigid3d& pose) {
  const Eigen::Matrix4d m = pose.ToMatrix();
  json rows = json::array();
  for (int r = 0; r < 4; ++r) rows.push_back({m(r, 0), m(r, 1), m(r, 2), m(r, 3)});
  return rows;
}

json ClipJson(const DriveClip& clip, size_t index) {
  json frames = json::array();
  for (size_t i = 0; i < clip.frames.size(); ++i) {
    const DriveFrame& f = clip.frames[i];
    const PinholeCamera& k = f.camera;
    char image[32];
    std::snprintf(image, sizeof(image), "images/%05zu.jpg", i);
    frames.push_back(
        {{"index", i},
         {"image", image},
         {"file", f.relative_path},
         {"path", fs::absolute(f.image_path).string()},
         {"timestamp_us", f.timestamp_us},
         {"sample_data_token", f.frame_id},
         {"is_keyframe", f.is_keyframe},
         {"intrinsics",
          {{"fx", k.fx}, {"fy", k.fy}, {"cx", k.cx}, {"cy", k.cy},
           {"width", k.width}, {"height", k.height},
           {"pixel_convention", "integer-index"}}},
         {"world_from_ego", Matrix(f.world_from_ego)},
         {"ego_from_cam", Matrix(f.ego_from_cam)},
         {"world_from_cam", Matrix(f.world_from_cam)}});
  }
  char sample[32];
  std::snprintf(sample, sizeof(sample), "sample_%06zu", index);
  return {{"format", "geodrive-clip"},
          {"version", 1},
          {"clip_id", clip.id},
          {"index", index},
          {"upstream_sample", sample},
          {"dataset", clip.dataset},
          {"scene", {{"name", clip.scene_name}, {"token", clip.scene_id}}},
          {"channel", clip.channel},
          {"frame_source", ToString(clip.frame_source)},
          {"frame_interval_s", clip.FrameIntervalSeconds()},
          {"units", clip.units},
          {"pose_convention",
           "4x4 row-major; world_from_cam = world_from_ego * ego_from_cam; "
           "camera axes OpenCV (x right, y down, z forward)"},
          {"frames", frames}};
}

// Links (or copies) the clip's images into DIR/images/%05d.jpg.
void LinkImages(const DriveClip& clip, const std::string& dir, bool copy) {
  const fs::path images = fs::path(dir) / "images";
  fs::create_directories(images);
  for (size_t i = 0; i < clip.frames.size(); ++i) {
    const std::string& src = clip.frames[i].image_path;
    char name[32];
    std::snprintf(name, sizeof(name), "%05zu.jpg", i);
    if (!fs::exists(src) && src.find('#') != std::string::npos) {
      // An image inside a container (a Waymo frame record): its JPEG as
      // stored, or the undistorted image (a PNG from the reader) as a
      // quality-95 JPEG.
      const ImageFile image = ReadImageFile(src);
      const std::string dst = (images / name).string();
      if (ReadImageHeader(image).jpeg)
        WriteFileAtomic(dst, image.bytes.data(), image.bytes.size());
      else
        WriteJpeg(dst, DecodeImageRgb(image), 95);
      continue;
    }
    GEODRIVE_CHECK_INPUT(fs::is_regular_file(src), src,
                         ": image listed in the dataset is missing on disk");
    const fs::path dst = images / name;
    std::error_code ec;
    fs::remove(dst, ec);
    if (copy) {
      fs::copy_file(src, dst, ec);
    } else {
      fs::create_symlink(fs::absolute(src), dst, ec);
    }
    GEODRIVE_CHECK_INPUT(!ec, dst.string(), ": cannot ",
                         copy ? "copy" : "link", " ", src, " (", ec.message(),
                         ")");
  }
}

int RunClips(ClipsArgs& a) {
  a.dataset.frames = ParseClipFrameSource(a.frames);
  a.dataset.format = ResolveDatasetFormat(a.format, a.dataset.root);
  CreateOutputDirectory(a.out);  // an unusable --out fails first
  const std::unique_ptr<DriveDataset> dataset = OpenDriveDataset(a.dataset);
  std::cerr << "clips: " << dataset->Describe() << "\n";
  std::vector<std::string> wanted;
  std::stringstream ss(a.clips);
  for (std::string id; std::getline(ss, id, ',');)
    if (!id.empty()) wanted.push_back(id);
  std::string index_text, failures_text;
  int written = 0, failed = 0;
  const std::vector<std::string>& ids = dataset->ClipIds();
  for (size_t i = 0; i < ids.size(); ++i) {
    if (!wanted.empty() &&
        std::find(wanted.begin(), wanted.end(), ids[i]) == wanted.end())
      continue;
    const std::string dir = a.out + "/" + ids[i];
    try {
      const DriveClip clip = dataset->LoadClip(ids[i]);
      LinkImages(clip, dir, a.copy);
      const json j = ClipJson(clip, i);
      WriteFileAtomic(dir + "/clip.json", j.dump(2) + "\n");
      index_text += json{{"clip_id", ids[i]},
                         {"index", i},
                         {"upstream_sample", j["upstream_sample"]},
                         {"dir", ids[i]},
                         {"num_frames", clip.num_frames()}}
                        .dump() +
                    "\n";
      ++written;
    } catch (const InputError& e) {
      failures_text += FailureEntryToJson({ids[i], "clip", e.what()}) + "\n";
      std::cerr << "clips: " << ids[i] << ": " << e.what() << "\n";
      ++failed;
    }
  }
  for (const std::string& id : wanted) {
    GEODRIVE_CHECK_INPUT(std::find(ids.begin(), ids.end(), id) != ids.end(),
                         "--clips: '", id, "' is not a clip of this dataset");
  }
  WriteFileAtomic(a.out + "/clips.jsonl", index_text);
  WriteFileAtomic(a.out + "/failures.jsonl", failures_text);
  std::cout << a.out << ": " << written << " clip(s) written, " << failed
            << " failed (missing files: see failures.jsonl)\n"
            << "run MonST3R on one: python demo.py --input_dir " << a.out
            << "/<clip_id>/images --output_dir MONST3R_ROOT --seq_name "
               "<clip_id>\n";
  return failed ? kExitCompletedWithFailures : kExitOk;
}

CommandRunner SetupClips(CLI::App& app) {
  auto a = std::make_shared<ClipsArgs>();
  app.footer(
      "Per clip OUT/<clip_id>/clip.json and OUT/<clip_id>/images/00000.jpg... "
      "(symlinks; --copy copies), plus OUT/clips.jsonl (clip id, index = the "
      "upstream sample_%06d number). Feed a folder to MonST3R:\n"
      "  python demo.py --input_dir OUT/<clip_id>/images --output_dir ROOT "
      "--seq_name <clip_id>\n"
      "then `geodrive build-dataset --monst3r ROOT` finds ROOT/<clip_id>/.");
  app.add_option("--dataroot", a->dataset.root,
                 "nuScenes root (holds <version>/, samples/, sweeps/), or a "
                 "folder of Waymo *.tfrecord segments")
      ->required();
  app.add_option("--dataset", a->format,
                 "nuscenes, waymo, or auto (waymo when --dataroot holds "
                 "*.tfrecord files)")
      ->check(CLI::IsMember({"auto", "nuscenes", "waymo"}))
      ->capture_default_str();
  app.add_option("--version", a->dataset.version, "Table folder")
      ->capture_default_str();
  app.add_option("--out", a->out, "Output folder")->required();
  app.add_option("--frames", a->frames,
                 "all (keyframes and sweeps) or keyframes (2 Hz samples)")
      ->check(CLI::IsMember({"all", "keyframes"}))
      ->capture_default_str();
  app.add_option("--clip-frames", a->dataset.clip_frames, "Frames per clip")
      ->capture_default_str();
  app.add_option("--stride", a->dataset.clip_stride,
                 "Frames between clip starts")
      ->capture_default_str();
  app.add_option("--clips", a->clips, "Comma-separated clip ids (default all)");
  app.add_flag("--copy", a->copy, "Copy the images instead of symlinking them");
  return [a] { return RunClips(*a); };
}

}  // namespace

GEODRIVE_REGISTER_COMMAND(
    clips,
    "clips",
    "Write each clip's frames (JSON + an image folder MonST3R can run on)",
    SetupClips);

}  // namespace geodrive
