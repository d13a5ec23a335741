// libFuzzer target: TFRecord framing (dataset/waymo/tfrecord.h) -- lengths,
// their CRCs, truncation, the size limit -- and, with the CRCs off so that
// mutated records get through, each record parsed as a Waymo v1 Frame
// (dataset/waymo/waymo_frame.h).
#include <string>

#include "dataset/waymo/tfrecord.h"
#include "dataset/waymo/waymo_frame.h"
#include "fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace geodrive;
  static const std::string path = fuzz::InputPath("segment.tfrecord");
  fuzz::WriteInput(path, data, size);
  TfRecordReaderOptions options;
  options.max_record_bytes = 64ull << 20;  // within libFuzzer's malloc limit
  fuzz::ExpectReturnOrInputError([&] { ReadTfRecords(path, options); });
  fuzz::ExpectReturnOrInputError([&] { CountTfRecords(path, options); });
  options.verify_crc = false;
  fuzz::ExpectReturnOrInputError([&] {
    TfRecordReader reader(path, options);
    std::string record;
    while (true) {
      const int64_t index = reader.index();
      if (!reader.Next(&record)) break;
      fuzz::ExpectReturnOrInputError(
          [&] { ParseWaymoFrame(record, path, index); });
    }
  });
  return 0;
}
