#pragma once
// Which predicted and ground-truth videos `geodrive eval` compares: pairing by
// clip id (render/video/video_io.h MatchVideos) over the whole ground-truth
// set, or over the subset that has a prediction (a `generate --limit N` run).

#include <string>
#include <vector>

#include "render/video/video_io.h"

namespace geodrive {

// The ground-truth videos an evaluation covers.
enum class EvalSubset {
  // Every ground-truth video needs a prediction (the default: a result over a
  // test set is never silently partial).
  kAll,
  // Only the ground-truth videos that have a prediction; the others are
  // counted and listed in the report.
  kPredicted,
};

// "all" or "predicted"; throws InputError naming --subset otherwise.
EvalSubset ParseEvalSubset(const std::string& text);
const char* ToString(EvalSubset subset);

// What a matching covered, for the report.
struct EvalSubsetSummary {
  EvalSubset subset = EvalSubset::kAll;
  // Ground-truth videos found under --gt.
  int ground_truth = 0;
  // Pairs evaluated (one per predicted video).
  int evaluated = 0;
  // Ids of the ground-truth videos without a prediction, sorted (always empty
  // for kAll, which refuses them).
  std::vector<std::string> without_prediction;

  // "2 predicted of 5 ground-truth videos evaluated (--subset predicted; 3
  // without a prediction: a, b, c)".
  std::string BriefReport() const;
};

struct EvalVideoMatch {
  std::vector<VideoPairSource> pairs;  // sorted by id
  EvalSubsetSummary summary;
};

// Pairs `pred` with `gt` by id. Every predicted video needs a ground truth with
// its id (two single videos pair regardless of names, as MatchVideos). kAll:
// every ground-truth video needs a prediction, else an InputError counts and
// names the missing ones and points to --subset predicted. kPredicted: the
// ground-truth videos without a prediction are left out and listed in the
// summary. Throws InputError.
EvalVideoMatch MatchEvalVideos(const std::vector<VideoSource>& pred,
                               const std::vector<VideoSource>& gt,
                               EvalSubset subset);

}  // namespace geodrive
