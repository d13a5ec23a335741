#include "geometry/pose_refinement.h"

#include <ceres/ceres.h>
#include <glog/logging.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <opencv2/calib3d.hpp>
#include <random>
#include <sstream>

#include "geometry/internal/cost_functions.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace {

using Clock = std::chrono::steady_clock;

// Pose as Ceres parameter blocks: cam_from_world, quaternion (w, x, y, z) +
// translation.
struct PoseParams {
  double q[4] = {1, 0, 0, 0};
  double t[3] = {0, 0, 0};

  static PoseParams FromWorldFromCam(const Rigid3d& world_from_cam) {
    const Rigid3d cam_from_world = world_from_cam.Inverse();
    PoseParams p;
    const Eigen::Quaterniond q = cam_from_world.rotation.normalized();
    p.q[0] = q.w(), p.q[1] = q.x(), p.q[2] = q.y(), p.q[3] = q.z();
    for (int k = 0; k < 3; ++k) p.t[k] = cam_from_world.translation[k];
    return p;
  }
  Rigid3d WorldFromCam() const {
    const Rigid3d cam_from_world(
        QuaternionFromWxyz(q[0], q[1], q[2], q[3]).normalized(),
        Eigen::Vector3d(t[0], t[1], t[2]));
    return cam_from_world.Inverse();
  }
};

// Sampled correspondences of one frame.
struct Correspondences {
  std::vector<Eigen::Vector3d> points;
  std::vector<Eigen::Vector2d> pixels;
  size_t size() const { return points.size(); }
};

Correspondences Gather(const PoseRefinementInput& input,
                       const PoseRefinementOptions& options,
                       int* num_valid) {
  const cv::Mat& pts = input.points_in_world;
  cv::Mat valid(pts.size(), CV_8UC1, cv::Scalar(0));
  for (int v = 0; v < pts.rows; ++v) {
    const auto* p = pts.ptr<cv::Vec3f>(v);
    const uint8_t* m =
        input.valid_mask.empty() ? nullptr : input.valid_mask.ptr<uint8_t>(v);
    uint8_t* out = valid.ptr<uint8_t>(v);
    for (int u = 0; u < pts.cols; ++u) {
      if ((!m || m[u]) && std::isfinite(p[u][0]) && std::isfinite(p[u][1]) &&
          std::isfinite(p[u][2])) {
        out[u] = 255;
      }
    }
  }
  *num_valid = cv::countNonZero(valid);
  Correspondences c;
  const uint32_t seed =
      options.seed + 7919u * static_cast<uint32_t>(input.frame_index);
  for (const auto& px :
       SamplePixelsStratified(valid, options.num_samples, seed)) {
    const cv::Vec3f& p = pts.at<cv::Vec3f>(px.y(), px.x());
    c.points.emplace_back(p[0], p[1], p[2]);
    c.pixels.emplace_back(px.x(), px.y());
  }
  return c;
}

// Per-correspondence reprojection error norms (px); points behind the camera
// get +inf.
std::vector<double> Errors(const Correspondences& c,
                           const Rigid3d& world_from_cam,
                           const PinholeCamera& cam,
                           double focal_scale) {
  const Rigid3d cam_from_world = world_from_cam.Inverse();
  const Eigen::Matrix3d R = cam_from_world.rotation.toRotationMatrix();
  std::vector<double> e(c.size());
  for (size_t i = 0; i < c.size(); ++i) {
    const Eigen::Vector3d x = R * c.points[i] + cam_from_world.translation;
    if (x.z() <= 0) {
      e[i] = std::numeric_limits<double>::infinity();
      continue;
    }
    const Eigen::Vector2d proj(focal_scale * cam.fx * x.x() / x.z() + cam.cx,
                               focal_scale * cam.fy * x.y() / x.z() + cam.cy);
    e[i] = (proj - c.pixels[i]).norm();
  }
  return e;
}

double Median(std::vector<double> v) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  auto mid = v.begin() + v.size() / 2;
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

double Rms(const std::vector<double>& e,
           double below = std::numeric_limits<double>::infinity(),
           int* count = nullptr) {
  double s = 0;
  int n = 0;
  for (double x : e) {
    if (x < below) s += x * x, ++n;
  }
  if (count) *count = n;
  if (below == std::numeric_limits<double>::infinity() &&
      n < static_cast<int>(e.size())) {
    return std::numeric_limits<double>::infinity();
  }
  return n ? std::sqrt(s / n) : 0.0;
}

int CountBehind(const std::vector<double>& e) {
  return static_cast<int>(
      std::count(e.begin(), e.end(), std::numeric_limits<double>::infinity()));
}

// OpenCV PnP RANSAC (EPnP inside RANSAC, refit on inliers). Returns false on
// failure.
bool PnpRansac(const Correspondences& c,
               const PinholeCamera& cam,
               const PoseRefinementOptions& options,
               Rigid3d* world_from_cam) {
  if (c.size() < 6) return false;
  std::vector<cv::Point3f> obj;
  std::vector<cv::Point2f> img;
  obj.reserve(c.size());
  img.reserve(c.size());
  for (size_t i = 0; i < c.size(); ++i) {
    obj.emplace_back(static_cast<float>(c.points[i].x()),
                     static_cast<float>(c.points[i].y()),
                     static_cast<float>(c.points[i].z()));
    img.emplace_back(static_cast<float>(c.pixels[i].x()),
                     static_cast<float>(c.pixels[i].y()));
  }
  const cv::Matx33d K(cam.fx, 0, cam.cx, 0, cam.fy, cam.cy, 0, 0, 1);
  cv::Mat rvec, tvec;
  std::vector<int> inliers;
  cv::setRNGSeed(static_cast<int>(options.seed));
  bool ok = false;
  try {
    ok = cv::solvePnPRansac(obj, img, K, cv::noArray(), rvec, tvec, false,
                            options.pnp_ransac_iterations,
                            static_cast<float>(options.pnp_ransac_threshold_px),
                            0.999, inliers, cv::SOLVEPNP_EPNP);
  } catch (const cv::Exception& e) {
    LOG(WARNING) << "solvePnPRansac failed: " << e.what();
    return false;
  }
  if (!ok || inliers.size() < 6) return false;
  const Eigen::Vector3d aa(rvec.at<double>(0), rvec.at<double>(1),
                           rvec.at<double>(2));
  const Rigid3d cam_from_world(
      QuaternionFromAngleAxis(aa),
      Eigen::Vector3d(tvec.at<double>(0), tvec.at<double>(1),
                      tvec.at<double>(2)));
  if (!cam_from_world.IsValid(1e-6)) return false;
  *world_from_cam = cam_from_world.Inverse();
  return true;
}

// One frame's state while solving.
struct FrameState {
  const PoseRefinementInput* input = nullptr;
  Correspondences corr;
  PoseParams params;
  PoseRefinementResult result;
  bool active = false;
};

// Prepares a frame: samples, initialisation (given / PnP), initial errors. Sets
// active = false and the skip reason for a degenerate frame.
void Prepare(const PoseRefinementInput& input,
             const PoseRefinementOptions& options,
             FrameState* state) {
  state->input = &input;
  PoseRefinementSummary& s = state->result.summary;
  s.frame_index = input.frame_index;
  state->result.camera = input.camera;
  state->result.world_from_cam =
      input.initial_world_from_cam.value_or(Rigid3d());
  if (input.points_in_world.empty() ||
      input.points_in_world.type() != CV_32FC3 ||
      (!input.valid_mask.empty() &&
       (input.valid_mask.size() != input.points_in_world.size() ||
        input.valid_mask.type() != CV_8UC1))) {
    s.skipped = true;
    s.skip_reason = "no CV_32FC3 pointmap, or a valid mask of another shape";
    return;
  }
  if (!input.camera.IsValid()) {
    s.skipped = true;
    s.skip_reason = "invalid camera intrinsics";
    return;
  }
  state->corr = Gather(input, options, &s.num_valid_pixels);
  s.num_residuals = static_cast<int>(state->corr.size());
  if (s.num_valid_pixels < options.min_valid_pixels) {
    s.skipped = true;
    s.skip_reason = "only " + std::to_string(s.num_valid_pixels) +
                    " static confident pixels (minimum " +
                    std::to_string(options.min_valid_pixels) + ")";
    return;
  }
  Rigid3d start;
  bool have_start = false;
  if (input.initial_world_from_cam &&
      input.initial_world_from_cam->IsValid(1e-6)) {
    start = *input.initial_world_from_cam;
    have_start = true;
    s.initialization = "given";
  }
  if (options.pnp_fallback) {
    bool far_off = !have_start;
    double given_median = std::numeric_limits<double>::infinity();
    if (have_start) {
      const auto e = Errors(state->corr, start, input.camera, 1.0);
      given_median = Median(e);
      far_off = given_median > options.pnp_trigger_px ||
                2 * CountBehind(e) > static_cast<int>(e.size());
    }
    Rigid3d pnp;
    if (far_off && PnpRansac(state->corr, input.camera, options, &pnp)) {
      const double pnp_median =
          Median(Errors(state->corr, pnp, input.camera, 1.0));
      if (pnp_median < given_median) {
        start = pnp;
        have_start = true;
        s.initialization = s.initialization.empty()
                               ? "pnp-ransac"
                               : "pnp-ransac (given pose far off)";
      }
    }
  }
  if (!have_start) {
    s.skipped = true;
    s.skip_reason = "no initial pose and PnP RANSAC failed";
    return;
  }
  state->params = PoseParams::FromWorldFromCam(start);
  state->result.world_from_cam = start;
  const auto e = Errors(state->corr, start, input.camera, 1.0);
  s.initial_rms_px = Rms(e);
  s.initial_median_px = Median(e);
  state->active = true;
}

ceres::LossFunction* MakeLoss(const PoseRefinementOptions& options) {
  switch (options.loss) {
    case RobustLoss::kHuber:
      return new ceres::HuberLoss(options.loss_scale_px);
    case RobustLoss::kCauchy:
      return new ceres::CauchyLoss(options.loss_scale_px);
    case RobustLoss::kNone:
      return nullptr;
  }
  return nullptr;
}

void AddFrameResiduals(FrameState* state,
                       double* focal_scale,
                       const PoseRefinementOptions& options,
                       ceres::Problem* problem) {
  const PinholeCamera& cam = state->input->camera;
  for (size_t i = 0; i < state->corr.size(); ++i) {
    problem->AddResidualBlock(
        ReprojectionCost::Create(state->corr.points[i], state->corr.pixels[i],
                                 cam.fx, cam.fy, cam.cx, cam.cy),
        MakeLoss(options), state->params.q, state->params.t, focal_scale);
  }
  problem->SetManifold(state->params.q, new ceres::QuaternionManifold);
}

ceres::Solver::Options SolverOptions(const PoseRefinementOptions& options,
                                     bool large) {
  ceres::Solver::Options so;
  so.max_num_iterations = options.max_iterations;
  so.function_tolerance = options.function_tolerance;
  so.gradient_tolerance = options.gradient_tolerance;
  so.parameter_tolerance = options.parameter_tolerance;
  so.num_threads = options.num_threads;
  so.minimizer_progress_to_stdout = false;
  so.logging_type = ceres::SILENT;
  if (!large) {
    so.linear_solver_type = ceres::DENSE_QR;
  } else if (ceres::IsSparseLinearAlgebraLibraryTypeAvailable(
                 ceres::SUITE_SPARSE)) {
    so.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
    so.sparse_linear_algebra_library_type = ceres::SUITE_SPARSE;
  } else if (ceres::IsSparseLinearAlgebraLibraryTypeAvailable(
                 ceres::EIGEN_SPARSE)) {
    so.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
    so.sparse_linear_algebra_library_type = ceres::EIGEN_SPARSE;
  } else {
    so.linear_solver_type = ceres::CGNR;
  }
  return so;
}

void Finish(FrameState* state,
            double focal_scale,
            const ceres::Solver::Summary& summary,
            double seconds,
            const PoseRefinementOptions& options) {
  PoseRefinementSummary& s = state->result.summary;
  state->result.world_from_cam = state->params.WorldFromCam();
  state->result.camera.fx = state->input->camera.fx * focal_scale;
  state->result.camera.fy = state->input->camera.fy * focal_scale;
  const auto e = Errors(state->corr, state->result.world_from_cam,
                        state->input->camera, focal_scale);
  s.final_rms_px = Rms(e);
  s.final_median_px = Median(e);
  s.final_inlier_rms_px = Rms(e, options.inlier_threshold_px, &s.num_inliers);
  s.final_focal_scale = focal_scale;
  s.iterations = static_cast<int>(summary.iterations.size());
  s.termination = ceres::TerminationTypeToString(summary.termination_type);
  s.usable =
      summary.IsSolutionUsable() && state->result.world_from_cam.IsValid(1e-6);
  s.seconds = seconds;
}

}  // namespace

std::string ToString(RobustLoss loss) {
  switch (loss) {
    case RobustLoss::kNone:
      return "none";
    case RobustLoss::kHuber:
      return "huber";
    case RobustLoss::kCauchy:
      return "cauchy";
  }
  return "?";
}

RobustLoss ParseRobustLoss(const std::string& text) {
  if (text == "none") return RobustLoss::kNone;
  if (text == "huber") return RobustLoss::kHuber;
  if (text == "cauchy") return RobustLoss::kCauchy;
  ThrowInputError("robust loss '" + text + "'",
                  "expected none, huber or cauchy");
}

void PoseRefinementOptions::Check() const {
  GEODRIVE_CHECK_INPUT(std::isfinite(loss_scale_px) && loss_scale_px > 0,
                       "loss_scale_px ", loss_scale_px, " must be positive");
  GEODRIVE_CHECK_INPUT(num_samples >= 0, "num_samples ", num_samples,
                       " must be >= 0");
  GEODRIVE_CHECK_INPUT(max_iterations >= 0, "max_iterations ", max_iterations,
                       " must be >= 0");
  GEODRIVE_CHECK_INPUT(num_threads >= 1 && num_threads <= 256, "num_threads ",
                       num_threads, " must be in 1..256");
  GEODRIVE_CHECK_INPUT(inlier_threshold_px > 0,
                       "inlier_threshold_px must be positive");
  GEODRIVE_CHECK_INPUT(min_valid_pixels >= 6, "min_valid_pixels ",
                       min_valid_pixels, " must be >= 6");
  GEODRIVE_CHECK_INPUT(pnp_trigger_px > 0 && pnp_ransac_threshold_px > 0 &&
                           pnp_ransac_iterations >= 1,
                       "PnP options must be positive");
  GEODRIVE_CHECK_INPUT(std::isfinite(smoothness_translation_weight) &&
                           smoothness_translation_weight >= 0 &&
                           std::isfinite(smoothness_rotation_weight) &&
                           smoothness_rotation_weight >= 0,
                       "smoothness weights must be >= 0");
}

std::string PoseRefinementSummary::BriefReport() const {
  std::ostringstream os;
  os << "frame " << frame_index << ": ";
  if (skipped) {
    os << "skipped (" << skip_reason << ")";
    return os.str();
  }
  os << "init " << initialization << ", " << num_residuals << " px of "
     << num_valid_pixels << ", rms " << initial_rms_px << " -> " << final_rms_px
     << " px (median " << initial_median_px << " -> " << final_median_px
     << "), inliers " << num_inliers << " (rms " << final_inlier_rms_px
     << " px), focal x" << final_focal_scale << ", " << iterations << " it, "
     << termination << ", " << seconds * 1e3 << " ms";
  return os.str();
}

std::vector<Eigen::Vector2i> SamplePixelsStratified(const cv::Mat& valid_mask,
                                                    int num_samples,
                                                    uint32_t seed) {
  CHECK_EQ(valid_mask.type(), CV_8UC1);
  const int w = valid_mask.cols, h = valid_mask.rows;
  std::vector<Eigen::Vector2i> out;
  if (num_samples == 0) {
    for (int v = 0; v < h; ++v) {
      const uint8_t* m = valid_mask.ptr<uint8_t>(v);
      for (int u = 0; u < w; ++u) {
        if (m[u]) out.emplace_back(u, v);
      }
    }
    return out;
  }
  // Grid of about num_samples / 4 cells with the image's aspect ratio.
  const double cells = std::max(1.0, num_samples / 4.0);
  const int gx =
      std::clamp(static_cast<int>(std::lround(std::sqrt(cells * w / h))), 1, w);
  const int gy = std::clamp(static_cast<int>(std::lround(cells / gx)), 1, h);
  std::vector<std::vector<int>> buckets(static_cast<size_t>(gx) * gy);
  for (int v = 0; v < h; ++v) {
    const uint8_t* m = valid_mask.ptr<uint8_t>(v);
    const int cy = v * gy / h;
    for (int u = 0; u < w; ++u) {
      if (m[u])
        buckets[static_cast<size_t>(cy) * gx + u * gx / w].push_back(v * w + u);
    }
  }
  std::mt19937 rng(seed);
  size_t total = 0;
  for (auto& b : buckets) {
    total += b.size();
  }
  const size_t want = std::min<size_t>(total, static_cast<size_t>(num_samples));
  out.reserve(want);
  // Partial Fisher-Yates per bucket, drawn lazily round by round.
  std::vector<size_t> drawn(buckets.size(), 0);
  while (out.size() < want) {
    for (size_t b = 0; b < buckets.size() && out.size() < want; ++b) {
      auto& bucket = buckets[b];
      size_t& k = drawn[b];
      if (k >= bucket.size()) continue;
      std::uniform_int_distribution<size_t> pick(k, bucket.size() - 1);
      std::swap(bucket[k], bucket[pick(rng)]);
      const int idx = bucket[k++];
      out.emplace_back(idx % w, idx / w);
    }
  }
  return out;
}

PoseRefinementResult RefineFramePose(const PoseRefinementInput& input,
                                     const PoseRefinementOptions& options) {
  options.Check();
  const auto start = Clock::now();
  FrameState state;
  Prepare(input, options, &state);
  if (!state.active) {
    state.result.summary.seconds =
        std::chrono::duration<double>(Clock::now() - start).count();
    return state.result;
  }
  double focal_scale = 1.0;
  ceres::Problem::Options po;
  po.loss_function_ownership = ceres::TAKE_OWNERSHIP;
  ceres::Problem problem(po);
  AddFrameResiduals(&state, &focal_scale, options, &problem);
  if (!options.refine_focal) problem.SetParameterBlockConstant(&focal_scale);
  ceres::Solver::Summary summary;
  ceres::Solve(SolverOptions(options, false), &problem, &summary);
  Finish(&state, focal_scale, summary,
         std::chrono::duration<double>(Clock::now() - start).count(), options);
  return state.result;
}

std::vector<PoseRefinementResult> RefineClipPoses(
    const std::vector<PoseRefinementInput>& inputs,
    const PoseRefinementOptions& options,
    bool joint) {
  options.Check();
  std::vector<PoseRefinementResult> results(inputs.size());
  if (!joint) {
#pragma omp parallel for schedule(dynamic) num_threads(options.num_threads)
    for (size_t i = 0; i < inputs.size(); ++i) {
      PoseRefinementOptions one = options;
      one.num_threads = 1;
      results[i] = RefineFramePose(inputs[i], one);
    }
    return results;
  }
  const auto start = Clock::now();
  std::vector<FrameState> states(inputs.size());
  for (size_t i = 0; i < inputs.size(); ++i)
    Prepare(inputs[i], options, &states[i]);
  double focal_scale = 1.0;
  ceres::Problem::Options po;
  po.loss_function_ownership = ceres::TAKE_OWNERSHIP;
  ceres::Problem problem(po);
  int active = 0;
  for (auto& s : states) {
    if (!s.active) continue;
    AddFrameResiduals(&s, &focal_scale, options, &problem);
    ++active;
  }
  if (active == 0) {
    for (size_t i = 0; i < states.size(); ++i) results[i] = states[i].result;
    return results;
  }
  if (!options.refine_focal) problem.SetParameterBlockConstant(&focal_scale);
  if (options.smoothness_translation_weight > 0 ||
      options.smoothness_rotation_weight > 0) {
    for (size_t i = 1; i + 1 < states.size(); ++i) {
      FrameState *a = &states[i - 1], *b = &states[i], *c = &states[i + 1];
      if (!a->active || !b->active || !c->active) continue;
      problem.AddResidualBlock(
          TemporalSmoothnessCost::Create(options.smoothness_translation_weight,
                                         options.smoothness_rotation_weight),
          nullptr, a->params.q, a->params.t, b->params.q, b->params.t,
          c->params.q, c->params.t);
    }
  }
  ceres::Solver::Summary summary;
  ceres::Solve(SolverOptions(options, true), &problem, &summary);
  const double seconds =
      std::chrono::duration<double>(Clock::now() - start).count();
  for (size_t i = 0; i < states.size(); ++i) {
    if (states[i].active)
      Finish(&states[i], focal_scale, summary, seconds, options);
    results[i] = states[i].result;
  }
  return results;
}

std::vector<PoseRefinementInput> PoseRefinementInputs(
    const Monst3rFolder& folder,
    const std::vector<int>& frames,
    const PointmapFilterOptions& filter) {
  Monst3rLoadOptions lo;
  lo.rgb = false;
  lo.raw_pointmaps = folder.has_raw_pointmaps();
  std::vector<PoseRefinementInput> inputs;
  for (const Monst3rFrame& f : folder.LoadFrames(frames, lo)) {
    const Pointmap pm = BuildPointmap(f);
    PoseRefinementInput in;
    in.frame_index = f.index;
    in.camera = f.camera;
    in.initial_world_from_cam = f.world_from_cam;
    in.points_in_world = f.raw_points_in_world.empty() ? pm.points_in_world
                                                       : f.raw_points_in_world;
    in.valid_mask = ComputeValidMask(pm, filter);
    inputs.push_back(std::move(in));
  }
  return inputs;
}

}  // namespace geodrive
