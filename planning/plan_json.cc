#include "planning/plan_json.h"

#include <cmath>
#include <nlohmann/json.hpp>

namespace geodrive {
namespace {

nlohmann::json Number(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
}

// A name or detail that does not apply (no collision, no rejection) is null,
// as a missing number is.
nlohmann::json Text(const std::string& v) {
  return v.empty() ? nlohmann::json(nullptr) : nlohmann::json(v);
}

nlohmann::json ScoresJson(const Candidate& c, const CandidateScores& s) {
  nlohmann::json j;
  j["name"] = s.name;
  j["source"] = c.source;
  j["waypoints"] = c.size();
  j["duration_s"] = Number(c.ego0_from_ego.Duration());
  j["rank"] = s.rank;
  j["cost"] = Number(s.cost);
  j["rejected"] = s.reject != RejectReason::kNone;
  j["reject_reason"] = ToString(s.reject);
  j["reject_detail"] = Text(s.reject_detail);
  j["collision"] = {
      {"collides", s.collides},
      {"first_time_s", Number(s.first_collision_time)},
      {"first_with", Text(s.first_collision_with)},
      {"first_with_category", Text(s.first_collision_category)},
      {"min_box_distance_m", Number(s.min_box_distance)},
      {"min_box_distance_time_s", Number(s.min_box_distance_time)},
      {"closest_obstacle", Text(s.closest_obstacle)}};
  j["drivable"] = {
      {"fraction", Number(s.drivable_fraction)},
      {"static_clearance_m", Number(s.static_clearance)},
      {"static_clearance_time_s", Number(s.static_clearance_time)}};
  const CandidateKinematics& k = s.kinematics;
  j["kinematics"] = {{"max_lon_accel_mps2", Number(k.max_lon_accel)},
                     {"max_lat_accel_mps2", Number(k.max_lat_accel)},
                     {"max_lon_jerk_mps3", Number(k.max_lon_jerk)},
                     {"max_lat_jerk_mps3", Number(k.max_lat_jerk)},
                     {"max_curvature_per_m", Number(k.max_curvature)},
                     {"max_speed_mps", Number(k.max_speed)},
                     {"envelope_violation", Text(s.envelope_violation)}};
  j["visibility"] = {{"mean_coverage", Number(s.mean_coverage)},
                     {"min_coverage", Number(s.min_coverage)}};
  j["logged"] = {{"ade_m", Number(s.ade)},
                 {"fde_m", Number(s.fde)},
                 {"progress_m", Number(s.progress)}};
  return j;
}

}  // namespace

std::string PlanResultToJson(const std::string& clip,
                             const std::vector<Candidate>& candidates,
                             const PlanResult& result,
                             const PlanScoreOptions& o) {
  nlohmann::json j;
  j["format"] = "geodrive-plan";
  j["version"] = 1;
  j["clip"] = clip;
  j["frame"] =
      "ego0: ego frame of the clip's first frame (x forward, y left, z up), "
      "metres";
  j["time"] = "seconds since the clip's first frame";
  j["ground_points"] = result.ground_points;
  j["obstacle_points"] = result.obstacle_points;
  j["options"] = {{"ego_length_m", o.ego_length},
                  {"ego_width_m", o.ego_width},
                  {"ego_height_m", o.ego_height},
                  {"ego_center_ahead_m", o.ego_center_ahead},
                  {"min_drivable_fraction", o.min_drivable_fraction},
                  {"envelope",
                   {{"max_curvature_per_m", o.envelope.max_curvature},
                    {"max_lon_accel_mps2", o.envelope.max_lon_accel},
                    {"max_lat_accel_mps2", o.envelope.max_lat_accel},
                    {"max_jerk_mps3", o.envelope.max_jerk}}},
                  {"weights",
                   {{"collision", o.weight_collision},
                    {"clearance_per_m", o.weight_clearance},
                    {"clearance_target_m", o.clearance_target},
                    {"offroad", o.weight_offroad},
                    {"static_clearance_per_m", o.weight_static_clearance},
                    {"ade_per_m", o.weight_ade},
                    {"accel_per_mps2", o.weight_accel},
                    {"jerk_per_mps3", o.weight_jerk},
                    {"progress_per_m", o.weight_progress}}}};
  nlohmann::json list = nlohmann::json::array();
  for (size_t i = 0; i < result.candidates.size(); ++i)
    list.push_back(ScoresJson(candidates[i], result.candidates[i]));
  j["candidates"] = list;
  nlohmann::json ranking = nlohmann::json::array();
  for (int i : result.ranking) ranking.push_back(result.candidates[i].name);
  j["ranking"] = ranking;
  return j.dump(2) + "\n";
}

}  // namespace geodrive
