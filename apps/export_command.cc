// `geodrive export`: other trainers' files added to the pairs of a finished
// build-dataset output, without rebuilding the pairs (dataset/exporter.h).

#include <iostream>
#include <memory>

#include "apps/cli/cli.h"
#include "dataset/build_dataset.h"
#include "dataset/exporter.h"

namespace geodrive {
namespace {

struct ExportArgs {
  std::string pairs;
  std::string formats;
  ExportOptions options;
  bool quiet = false;
};

CommandRunner SetupExport(CLI::App& app) {
  auto a = std::make_shared<ExportArgs>();
  app.footer(
      "Each pair's clip is loaded again and its scene built and rendered "
      "with the pair's own options\n(meta.json), so that a condition is "
      "rendered at its trainer's size; the files go into the\npair folders "
      "as build-dataset --export writes them, then each format's index "
      "under OUT/\n(docs/how-to/export.md).");
  app.add_option("--pairs", a->pairs,
                 "A build-dataset output (OUT: manifest.jsonl, pairs/)")
      ->required();
  app.add_option("--format", a->formats,
                 "FORMAT[,FORMAT...]: geodrive-upstream, streetcrafter, "
                 "gen3c, rds-hq, drivestudio")
      ->required();
  app.add_option("--val-fraction", a->options.val_fraction,
                 "Formats with train/val lists (streetcrafter, rds-hq): "
                 "fraction of the scenes listed for validation (by scene, "
                 "seeded)")
      ->capture_default_str();
  app.add_option("--split-seed", a->options.split_seed,
                 "Seed of the by-scene train/val split")
      ->capture_default_str();
  app.add_flag("--quiet", a->quiet, "No progress output");
  return [a] {
    const int n = ExportPairs(a->pairs, ParseExportFormats(a->formats),
                              a->options, a->quiet);
    std::cout << "exported " << n << " pairs of " << a->pairs << " as "
              << ToString(ParseExportFormats(a->formats)) << "\n";
    return kExitOk;
  };
}

}  // namespace

GEODRIVE_REGISTER_COMMAND(
    export_pairs,
    "export",
    "Write other trainers' files (streetcrafter, gen3c, rds-hq, "
    "drivestudio, geodrive-upstream) for the pairs of a build-dataset output",
    SetupExport);

}  // namespace geodrive
