// Which ground-truth videos `geodrive eval` compares (eval/video_matching.h):
// the strict default, the predicted subset, and the errors of both.

#include "eval/video_matching.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "geometry/util/status.h"

namespace geodrive {
namespace {

std::vector<VideoSource> Videos(const std::vector<std::string>& ids,
                                const std::string& dir) {
  std::vector<VideoSource> out;
  for (const std::string& id : ids)
    out.push_back({id, dir + "/" + id + ".mp4"});
  return out;
}

std::string ErrorOf(const std::vector<VideoSource>& pred,
                    const std::vector<VideoSource>& gt,
                    EvalSubset subset) {
  try {
    MatchEvalVideos(pred, gt, subset);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(EvalSubset, AllMatchesEveryGroundTruthVideo) {
  const EvalVideoMatch m =
      MatchEvalVideos(Videos({"b", "a", "c"}, "pred"),
                      Videos({"a", "b", "c"}, "gt"), EvalSubset::kAll);
  ASSERT_EQ(m.pairs.size(), 3u);
  EXPECT_EQ(m.pairs[0].id, "a");
  EXPECT_EQ(m.pairs[0].pred_path, "pred/a.mp4");
  EXPECT_EQ(m.pairs[0].gt_path, "gt/a.mp4");
  EXPECT_EQ(m.summary.evaluated, 3);
  EXPECT_EQ(m.summary.ground_truth, 3);
  EXPECT_TRUE(m.summary.without_prediction.empty());
  EXPECT_EQ(m.summary.BriefReport(),
            "3 of 3 ground-truth videos evaluated (--subset all)");
}

TEST(EvalSubset, AllRefusesMissingPredictionsAndNamesTheOption) {
  const std::string error =
      ErrorOf(Videos({"a", "b"}, "pred"), Videos({"a", "b", "c"}, "gt"),
              EvalSubset::kAll);
  EXPECT_NE(error.find("1 of 3 ground-truth videos have no prediction with "
                       "the same id (c)"),
            std::string::npos)
      << error;
  EXPECT_NE(error.find("--subset predicted"), std::string::npos) << error;
  // More than five missing: the first five, then "...".
  const std::string many = ErrorOf(
      Videos({"a"}, "pred"),
      Videos({"a", "b", "c", "d", "e", "f", "g", "h"}, "gt"), EvalSubset::kAll);
  EXPECT_NE(many.find("7 of 8 ground-truth videos have no prediction with the "
                      "same id (b, c, d, e, f, ...)"),
            std::string::npos)
      << many;
}

TEST(EvalSubset, PredictedEvaluatesTheSubsetAndListsTheRest) {
  const EvalVideoMatch m = MatchEvalVideos(Videos({"b", "d"}, "pred"),
                                           Videos({"a", "b", "c", "d"}, "gt"),
                                           EvalSubset::kPredicted);
  ASSERT_EQ(m.pairs.size(), 2u);
  EXPECT_EQ(m.pairs[0].id, "b");
  EXPECT_EQ(m.pairs[1].id, "d");
  EXPECT_EQ(m.pairs[1].gt_path, "gt/d.mp4");
  EXPECT_EQ(m.summary.evaluated, 2);
  EXPECT_EQ(m.summary.ground_truth, 4);
  EXPECT_EQ(m.summary.without_prediction, (std::vector<std::string>{"a", "c"}));
  EXPECT_EQ(m.summary.BriefReport(),
            "2 predicted of 4 ground-truth videos evaluated (--subset "
            "predicted; 2 without a prediction: a, c)");
  // One prediction among many ground-truth videos pairs by id.
  const EvalVideoMatch one =
      MatchEvalVideos(Videos({"c"}, "pred"), Videos({"a", "b", "c"}, "gt"),
                      EvalSubset::kPredicted);
  ASSERT_EQ(one.pairs.size(), 1u);
  EXPECT_EQ(one.pairs[0].gt_path, "gt/c.mp4");
  EXPECT_EQ(one.summary.without_prediction,
            (std::vector<std::string>{"a", "b"}));
  // Every ground truth predicted: the subset is the whole set.
  const EvalVideoMatch all =
      MatchEvalVideos(Videos({"a", "b"}, "pred"), Videos({"a", "b"}, "gt"),
                      EvalSubset::kPredicted);
  EXPECT_EQ(all.summary.BriefReport(),
            "2 predicted of 2 ground-truth videos evaluated (--subset "
            "predicted; 0 without a prediction)");
}

TEST(EvalSubset, PredictionWithoutGroundTruthIsAnErrorInBothModes) {
  for (EvalSubset subset : {EvalSubset::kAll, EvalSubset::kPredicted}) {
    const std::string error =
        ErrorOf(Videos({"a", "x"}, "pred"), Videos({"a", "b"}, "gt"), subset);
    EXPECT_NE(error.find("1 predicted videos have no ground truth with the "
                         "same id (x)"),
              std::string::npos)
        << ToString(subset) << ": " << error;
  }
}

TEST(EvalSubset, TwoSingleVideosPairRegardlessOfNames) {
  for (EvalSubset subset : {EvalSubset::kAll, EvalSubset::kPredicted}) {
    const EvalVideoMatch m = MatchEvalVideos(Videos({"sample"}, "pred"),
                                             Videos({"gt"}, "gt"), subset);
    ASSERT_EQ(m.pairs.size(), 1u);
    EXPECT_EQ(m.pairs[0].pred_path, "pred/sample.mp4");
    EXPECT_EQ(m.summary.evaluated, 1);
    EXPECT_TRUE(m.summary.without_prediction.empty());
  }
}

TEST(EvalSubset, ParseNamesTheOption) {
  EXPECT_EQ(ParseEvalSubset("all"), EvalSubset::kAll);
  EXPECT_EQ(ParseEvalSubset("predicted"), EvalSubset::kPredicted);
  EXPECT_STREQ(ToString(EvalSubset::kPredicted), "predicted");
  try {
    ParseEvalSubset("some");
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("--subset"), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace geodrive
