#include "geometry/reconstruction.h"

#include <mutex>

#include "geometry/reconstruction/common.h"
#include "geometry/util/status.h"

namespace geodrive {

std::string ToString(ReconstructionFormat format) {
  switch (format) {
    case ReconstructionFormat::kMonst3r:
      return "monst3r";
    case ReconstructionFormat::kVggt:
      return "vggt";
    case ReconstructionFormat::kDepthAnything3:
      return "da3";
    case ReconstructionFormat::kCut3r:
      return "cut3r";
    case ReconstructionFormat::kMegaSam:
      return "megasam";
    case ReconstructionFormat::kMoge:
      return "moge";
    case ReconstructionFormat::kGenericNpz:
      return "npz";
  }
  return "?";
}

std::vector<ReconstructionFormat> AllReconstructionFormats() {
  return {ReconstructionFormat::kMonst3r,        ReconstructionFormat::kVggt,
          ReconstructionFormat::kDepthAnything3, ReconstructionFormat::kCut3r,
          ReconstructionFormat::kMegaSam,        ReconstructionFormat::kMoge,
          ReconstructionFormat::kGenericNpz};
}

ReconstructionFormat ParseReconstructionFormat(const std::string& text) {
  std::string names;
  for (ReconstructionFormat f : AllReconstructionFormats()) {
    if (text == ToString(f)) return f;
    names += (names.empty() ? "" : ", ") + ToString(f);
  }
  ThrowInputError("reconstruction format", "unknown format '", text,
                  "' (expected one of ", names, ")");
}

bool ReconstructionReadOptions::Check() const { return max_bytes > 0; }

namespace {
std::mutex& VideoDecoderMutex() {
  static std::mutex m;
  return m;
}
ReconstructionVideoDecoder& VideoDecoder() {
  static ReconstructionVideoDecoder decoder;
  return decoder;
}
}  // namespace

void SetReconstructionVideoDecoder(ReconstructionVideoDecoder decoder) {
  const std::lock_guard<std::mutex> lock(VideoDecoderMutex());
  VideoDecoder() = std::move(decoder);
}

ReconstructionVideoDecoder GetReconstructionVideoDecoder() {
  const std::lock_guard<std::mutex> lock(VideoDecoderMutex());
  return VideoDecoder();
}

std::unique_ptr<ReconstructionReader> CreateReconstructionReader(
    ReconstructionFormat format) {
  switch (format) {
    case ReconstructionFormat::kMonst3r:
      return reconstruction::CreateMonst3rReader();
    case ReconstructionFormat::kVggt:
      return reconstruction::CreateVggtReader();
    case ReconstructionFormat::kDepthAnything3:
      return reconstruction::CreateDepthAnything3Reader();
    case ReconstructionFormat::kCut3r:
      return reconstruction::CreateCut3rReader();
    case ReconstructionFormat::kMegaSam:
      return reconstruction::CreateMegaSamReader();
    case ReconstructionFormat::kMoge:
      return reconstruction::CreateMogeReader();
    case ReconstructionFormat::kGenericNpz:
      return reconstruction::CreateGenericNpzReader();
  }
  ThrowInputError("reconstruction format", "unknown format");
}

std::unique_ptr<ReconstructionReader> CreateReconstructionReaderFor(
    ReconstructionFormat format, const std::string& path) {
  if (format == ReconstructionFormat::kGenericNpz &&
      reconstruction::HasGen3cExportFiles(path))
    return reconstruction::CreateGen3cExportReader();
  return CreateReconstructionReader(format);
}

std::optional<ReconstructionFormat> DetectReconstructionFormat(
    const std::string& path) {
  // The generic npz last: its keys are the least specific.
  for (ReconstructionFormat f : AllReconstructionFormats()) {
    if (CreateReconstructionReader(f)->Locate(path)) return f;
  }
  return std::nullopt;
}

Monst3rFolder ReadReconstruction(ReconstructionFormat format,
                                 const std::string& path,
                                 const ReconstructionReadOptions& options) {
  GEODRIVE_CHECK_INPUT(options.Check(), path, ": bad read options");
  return CreateReconstructionReader(format)->Read(path, options);
}

}  // namespace geodrive
