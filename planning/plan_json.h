#pragma once
// plan.json: the scores, ranking and rejection reasons of a plan, with the
// units and the options that produced them (data_schema/plan.schema.json
// is not written yet; docs/PLANNING.md lists the fields).

#include <string>
#include <vector>

#include "planning/candidates.h"
#include "planning/scores.h"

namespace geodrive {

// The JSON text (2-space indent, NaN and infinity written as null). `clip`
// names the scene (may be empty).
std::string PlanResultToJson(const std::string& clip,
                             const std::vector<Candidate>& candidates,
                             const PlanResult& result,
                             const PlanScoreOptions& options);

}  // namespace geodrive
