// The streaming LZF decoder (geometry/internal/lzf_stream.h) against liblzf,
// the reference: the same bytes for every stream liblzf writes, and the same
// verdict (and, for short streams, the same length) on corrupted ones.

#include "geometry/internal/lzf_stream.h"

#include <gtest/gtest.h>
#include <liblzf/lzf.h>  // Debian's liblzf-dev, the reference

#include <cstdint>
#include <cstring>
#include <random>
#include <string>
#include <vector>

namespace geodrive {
namespace {

using lzf_stream::DecodeLzf;
using lzf_stream::DecodeLzfStream;
using lzf_stream::LzfResult;

// Collects the decoded bytes. With `hold` > 0 it leaves up to `hold` bytes
// of a piece unused (handed again next time), as a sink converting whole
// values does; the final piece it uses whole.
struct CollectingSink {
  uint64_t out_size = 0;
  size_t hold = 0;
  std::string bytes;
  int calls = 0;
  bool bad_offset = false;

  size_t Consume(uint64_t offset, const uint8_t* data, size_t n) {
    ++calls;
    if (offset != bytes.size()) bad_offset = true;
    size_t use = n;
    if (offset + n < out_size && hold > 0)
      use = n - std::min(n, (offset + n) % (hold + 1));
    bytes.append(reinterpret_cast<const char*>(data), use);
    return use;
  }
};

std::vector<uint8_t> Compress(const std::string& raw) {
  std::vector<uint8_t> out(raw.size() + raw.size() / 16 + 64);
  const unsigned got =
      lzf_compress(raw.data(), static_cast<unsigned>(raw.size()), out.data(),
                   static_cast<unsigned>(out.size()));
  EXPECT_GT(got, 0u);
  out.resize(got);
  return out;
}

// Data with the structures LZF meets in point clouds: incompressible noise,
// runs of one byte, repeating patterns of every period up to 20 (LZF's
// overlapping copies), float columns, and a mix with short literals.
std::vector<std::string> Samples() {
  std::mt19937 rng(7);
  std::vector<std::string> samples;
  std::string noise(100000, '\0');
  for (char& c : noise) c = static_cast<char>(rng());
  samples.push_back(noise);
  samples.push_back(std::string(70000, '\0'));
  // Longer than LZF's 8 KiB window, so the decoder's unchecked fast loop
  // (which starts past it) copies overlapping back-references too.
  for (int period = 1; period <= 20; ++period) {
    std::string s;
    for (int k = 0; k < 12000 + period; ++k)
      s.push_back(static_cast<char>('a' + (k % period)));
    samples.push_back(s);
  }
  std::string floats;
  std::uniform_real_distribution<float> u(-50, 50);
  for (int k = 0; k < 40000; ++k) {
    const float v = k % 7 == 0 ? 1.0f : u(rng);
    floats.append(reinterpret_cast<const char*>(&v), 4);
  }
  samples.push_back(floats);
  std::string mixed;
  for (int k = 0; k < 20000; ++k) {
    if (rng() % 3 == 0)
      mixed.push_back(static_cast<char>(rng()));
    else
      mixed.append(
          mixed.empty() ? "x" : mixed.substr(mixed.size() / 2, 1 + rng() % 9));
  }
  samples.push_back(mixed);
  for (size_t n : {1, 2, 3, 31, 32, 33, 64, 300})
    samples.push_back(noise.substr(0, n));
  return samples;
}

TEST(LzfStream, DecodesWhatLiblzfWritesForAnyPieceSize) {
  for (const std::string& raw : Samples()) {
    const std::vector<uint8_t> packed = Compress(raw);
    for (size_t piece : {1, 7, 100, 4096, 1 << 18}) {
      for (size_t hold : {0, 3, 9}) {
        CollectingSink sink;
        sink.out_size = raw.size();
        sink.hold = hold;
        uint64_t produced = 0;
        const LzfResult r = DecodeLzf(packed.data(), packed.size(), raw.size(),
                                      piece, sink, &produced);
        ASSERT_EQ(r, LzfResult::kOk) << raw.size() << " bytes, piece " << piece;
        EXPECT_EQ(produced, raw.size());
        EXPECT_FALSE(sink.bad_offset);
        ASSERT_EQ(sink.bytes, raw)
            << raw.size() << " bytes, piece " << piece << ", hold " << hold;
        if (piece == 1 && raw.size() > 20000) {
          EXPECT_GT(sink.calls, 2);
        }
      }
    }
  }
}

// DecodeLzfStream over `in`, read `input_bytes` at a time; `fail_after`:
// reads that succeed before one fails.
LzfResult DecodeInChunks(const std::vector<uint8_t>& in,
                         uint64_t out_size,
                         size_t piece,
                         size_t input_bytes,
                         CollectingSink* sink,
                         uint64_t* produced,
                         int fail_after = -1) {
  size_t at = 0;
  int reads = 0;
  return DecodeLzfStream(in.size(), out_size, piece, input_bytes, *sink,
                         produced, [&](uint8_t* dst, size_t n) {
                           if (reads++ == fail_after) return false;
                           EXPECT_LE(at + n, in.size());
                           std::memcpy(dst, in.data() + at, n);
                           at += n;
                           return true;
                         });
}

TEST(LzfStream, DecodesAStreamReadInChunksOfAnySize) {
  for (const std::string& raw : Samples()) {
    const std::vector<uint8_t> packed = Compress(raw);
    for (size_t input_bytes : {1, 64, 65, 97, 1000, 1 << 16}) {
      for (size_t piece : {7, 4096}) {
        CollectingSink sink;
        sink.out_size = raw.size();
        sink.hold = 3;
        uint64_t produced = 0;
        ASSERT_EQ(DecodeInChunks(packed, raw.size(), piece, input_bytes, &sink,
                                 &produced),
                  LzfResult::kOk)
            << raw.size() << " bytes, chunks of " << input_bytes;
        ASSERT_EQ(sink.bytes, raw)
            << raw.size() << " bytes, chunks of " << input_bytes;
      }
    }
  }
}

TEST(LzfStream, StopsWhenAReadFails) {
  for (const std::string& raw : Samples()) {
    const std::vector<uint8_t> packed = Compress(raw);
    if (packed.size() < 1000) continue;
    for (int fail_after : {0, 1, 5}) {
      CollectingSink sink;
      sink.out_size = raw.size();
      uint64_t produced = 0;
      EXPECT_EQ(DecodeInChunks(packed, raw.size(), 64, 100, &sink, &produced,
                               fail_after),
                LzfResult::kInputStopped);
      EXPECT_LT(produced, raw.size());
      // What was handed out is the stream's true start.
      EXPECT_EQ(sink.bytes, raw.substr(0, sink.bytes.size()));
    }
  }
}

// Corrupted streams: flipped bytes, cut or extended input, a wrong declared
// size. liblzf's verdict: the stream decodes to exactly the declared size
// (ok), stops short of it (its return value), or fails (0).
TEST(LzfStream, SameVerdictAsLiblzfOnCorruptedStreams) {
  std::mt19937 rng(11);
  int ok = 0, short_streams = 0, failed = 0;
  for (const std::string& raw : Samples()) {
    const std::vector<uint8_t> packed = Compress(raw);
    for (int trial = 0; trial < 60; ++trial) {
      std::vector<uint8_t> bad = packed;
      uint64_t out_size = raw.size();
      switch (trial % 4) {
        case 0:  // flip a few bytes
          for (int k = 0; k < 1 + trial % 3; ++k)
            bad[rng() % bad.size()] ^= static_cast<uint8_t>(1 + rng() % 255);
          break;
        case 1:  // cut the input
          bad.resize(1 + rng() % bad.size());
          break;
        case 2:  // extend it with noise
          for (int k = 0; k < 1 + trial % 40; ++k)
            bad.push_back(static_cast<uint8_t>(rng()));
          break;
        default:  // declare another size
          out_size = rng() % 2 ? raw.size() + 1 + rng() % 50
                               : raw.size() - rng() % raw.size();
          if (out_size == 0) out_size = 1;
          break;
      }
      std::vector<uint8_t> reference(out_size + 1);
      const unsigned got =
          lzf_decompress(bad.data(), static_cast<unsigned>(bad.size()),
                         reference.data(), static_cast<unsigned>(out_size));
      CollectingSink sink;
      sink.out_size = out_size;
      uint64_t produced = 0;
      const LzfResult r =
          DecodeLzf(bad.data(), bad.size(), out_size, 64, sink, &produced);
      {  // the same verdict and output when read in small chunks
        CollectingSink chunked;
        chunked.out_size = out_size;
        uint64_t chunked_produced = 0;
        ASSERT_EQ(DecodeInChunks(bad, out_size, 64, 64 + trial % 50, &chunked,
                                 &chunked_produced),
                  r)
            << "trial " << trial;
        ASSERT_EQ(chunked_produced, produced) << "trial " << trial;
        ASSERT_EQ(chunked.bytes, sink.bytes) << "trial " << trial;
      }
      if (got == out_size) {
        ++ok;
        ASSERT_EQ(r, LzfResult::kOk) << "trial " << trial;
        ASSERT_EQ(
            sink.bytes,
            std::string(reinterpret_cast<char*>(reference.data()), out_size));
      } else if (got > 0) {
        ++short_streams;
        ASSERT_EQ(r, LzfResult::kShort) << "trial " << trial;
        EXPECT_EQ(produced, got);
      } else {
        ++failed;
        ASSERT_TRUE(r == LzfResult::kInvalid || r == LzfResult::kTooLong)
            << "trial " << trial;
      }
    }
  }
  // Every kind of outcome was exercised.
  EXPECT_GT(ok, 20);
  EXPECT_GT(short_streams, 20);
  EXPECT_GT(failed, 100);
}

TEST(LzfStream, BackReferenceBeforeTheStartIsInvalid) {
  // A literal "ab", then a back-reference of 3 bytes from 3 bytes back (one
  // before the start): control (1 << 5) | 0, distance byte 2.
  const uint8_t stream[] = {1, 'a', 'b', 1 << 5, 2};
  CollectingSink sink;
  sink.out_size = 5;
  uint64_t produced = 0;
  EXPECT_EQ(DecodeLzf(stream, sizeof stream, 5, 64, sink, &produced),
            LzfResult::kInvalid);
  EXPECT_EQ(produced, 2u);
  // From 2 bytes back it is fine: "ab" + "aba".
  const uint8_t good[] = {1, 'a', 'b', 1 << 5, 1};
  CollectingSink sink2;
  sink2.out_size = 5;
  EXPECT_EQ(DecodeLzf(good, sizeof good, 5, 64, sink2, &produced),
            LzfResult::kOk);
  EXPECT_EQ(sink2.bytes, "ababa");
}

}  // namespace
}  // namespace geodrive
