#include "eval/video_matching.h"

#include <algorithm>
#include <set>
#include <sstream>

#include "geometry/util/status.h"

namespace geodrive {
namespace {

// "a, b, c" (at most `max` ids, then ", ...").
std::string IdList(const std::vector<std::string>& ids, size_t max = 5) {
  std::string out;
  for (size_t i = 0; i < ids.size() && i < max; ++i)
    out += (i ? ", " : "") + ids[i];
  if (ids.size() > max) out += ", ...";
  return out;
}

}  // namespace

EvalSubset ParseEvalSubset(const std::string& text) {
  if (text == "all") return EvalSubset::kAll;
  if (text == "predicted") return EvalSubset::kPredicted;
  ThrowInputError("--subset", "unknown value '", text,
                  "' (expected all or predicted)");
}

const char* ToString(EvalSubset subset) {
  return subset == EvalSubset::kPredicted ? "predicted" : "all";
}

std::string EvalSubsetSummary::BriefReport() const {
  std::ostringstream os;
  if (subset == EvalSubset::kAll) {
    os << evaluated << " of " << ground_truth
       << " ground-truth videos evaluated (--subset all)";
    return os.str();
  }
  os << evaluated << " predicted of " << ground_truth
     << " ground-truth videos evaluated (--subset predicted; "
     << without_prediction.size() << " without a prediction"
     << (without_prediction.empty() ? "" : ": " + IdList(without_prediction))
     << ")";
  return os.str();
}

EvalVideoMatch MatchEvalVideos(const std::vector<VideoSource>& pred,
                               const std::vector<VideoSource>& gt,
                               EvalSubset subset) {
  EvalVideoMatch out;
  out.summary.subset = subset;
  out.summary.ground_truth = static_cast<int>(gt.size());
  std::vector<VideoSource> gt_used = gt;
  // Two single videos pair regardless of their names (MatchVideos).
  if (!(pred.size() == 1 && gt.size() == 1)) {
    std::set<std::string> pred_ids, gt_ids;
    for (const VideoSource& v : pred) pred_ids.insert(v.id);
    for (const VideoSource& v : gt) gt_ids.insert(v.id);
    // A prediction without a ground truth is an error in both modes.
    std::vector<std::string> unmatched;
    for (const std::string& id : pred_ids) {
      if (!gt_ids.count(id)) unmatched.push_back(id);
    }
    GEODRIVE_CHECK_INPUT(unmatched.empty(), "eval: ", unmatched.size(),
                         " predicted videos have no ground truth with the "
                         "same id (",
                         IdList(unmatched), ")");
    std::vector<std::string> missing;
    gt_used.clear();
    for (const VideoSource& v : gt) {
      if (pred_ids.count(v.id)) {
        gt_used.push_back(v);
      } else {
        missing.push_back(v.id);
      }
    }
    std::sort(missing.begin(), missing.end());
    GEODRIVE_CHECK_INPUT(
        subset == EvalSubset::kPredicted || missing.empty(),
        "eval: ", missing.size(), " of ", gt.size(),
        " ground-truth videos have no prediction with the same id (",
        IdList(missing),
        "); --subset predicted evaluates only the videos that have one");
    out.summary.without_prediction = missing;
  }
  out.pairs = MatchVideos(pred, gt_used);
  out.summary.evaluated = static_cast<int>(out.pairs.size());
  return out;
}

}  // namespace geodrive
