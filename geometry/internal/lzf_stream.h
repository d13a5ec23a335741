#pragma once
// LZF decoding in bounded memory, for PCD binary_compressed.
//
// Why not liblzf's lzf_decompress (which the tests still use as the
// reference): it copies literal runs and back-references byte by byte (about
// 2 GB/s on a 2-vCPU development machine, on float data that hardly compresses)
// and it needs the whole output in one buffer (160 MB for 10 M points,
// page-faulted fresh on every read), and the whole input too. This decoder
// reads its input in chunks, copies 16 and 32 bytes at a time where the
// stream allows it, and hands its output to a sink in pieces while keeping
// only one input chunk, LZF's 8 KiB back-reference window and one piece in
// memory. Same format and the same verdicts as liblzf 3.6 with CHECK_INPUT:
// tests/geometry/lzf_stream_test.cc compares outputs and errors on streams
// written by liblzf and on corrupted ones.
//
// The format: a control byte c. c < 32: a literal run of c + 1 bytes
// follows. Otherwise a back-reference: length l = c >> 5 (7: plus the next
// byte), then the low distance byte; it copies l + 2 bytes from
// d = ((c & 31) << 8) + low + 1 bytes back (so d <= 8192; copies may overlap
// their own output).

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <vector>

namespace geodrive {
namespace lzf_stream {

enum class LzfResult {
  kOk,
  // A run or back-reference that needs bytes past the input's end, or a
  // back-reference to before the output's start.
  kInvalid,
  // The stream expands to more than the declared size.
  kTooLong,
  // The input ended before the declared size was reached.
  kShort,
  // DecodeLzfStream's read failed: the rest of the stream never arrived.
  kInputStopped,
};

// Largest back-reference distance, and the most bytes one instruction
// writes (a 32-byte literal copy, or a back-reference of 7 + 255 + 2 bytes
// copied 16 at a time).
constexpr size_t kWindow = 8192;
constexpr size_t kSlack = 512;
// The most input bytes one instruction reads (a control byte and a 32-byte
// literal run).
constexpr size_t kMaxInstructionBytes = 33;
// The most bytes one instruction writes (a back-reference of 7 + 255 + 2),
// and more input bytes than one instruction reads (a control byte and a
// 32-byte literal run read as 32).
constexpr size_t kMaxInstructionOutput = 264;
constexpr size_t kFastInput = 34;

// Copies a back-reference of `len` bytes from `dist` bytes back (the copy may
// overlap its own output, as LZF means it to). Writes up to 15 bytes past
// len, into the decoder's slack.
inline void CopyBackReference(uint8_t* dst, size_t dist, size_t len) {
  const uint8_t* ref = dst - dist;
  if (len <= 4) {  // XPERIMENT
    dst[0] = ref[0];
    dst[1] = ref[1];
    dst[2] = ref[2];
    if (len == 4) dst[3] = ref[3];
    return;
  }
  if (dist >= 16 || len <= dist) {
    // Each 16-byte load ends at or before the bytes its store must get right
    // are written: from dist >= 16 back, or, for len <= dist < 16, in one
    // load whose bytes past len land in the slack. (The most common short
    // back-reference on float data, 3 bytes from 4 back, takes this path.)
    for (size_t k = 0; k < len; k += 16) {
      uint8_t chunk[16];
      std::memcpy(chunk, ref + k, 16);
      std::memcpy(dst + k, chunk, 16);
    }
    return;
  }
  // A period shorter than 16 that the copy repeats: the first bytes one by
  // one, until a multiple of the period that is >= 8 is written
  // (dist * ceil(8 / dist), from a table: no division); from there 8-byte
  // copies from that many bytes back repeat the same pattern.
  static constexpr uint8_t kStep[16] = {0, 8, 8,  9,  8,  10, 12, 14,
                                        8, 9, 10, 11, 12, 13, 14, 15};
  const size_t step = kStep[dist];
  size_t k = 0;
  for (; k < len && k < step; ++k) dst[k] = ref[k];
  for (; k < len; k += 8) std::memcpy(dst + k, dst + k - step, 8);
}

// The decoder's state between pieces.
struct LzfCursor {
  const uint8_t* ip;
  const uint8_t* in_end;
  uint8_t* buf;
  size_t op;    // write position in buf
  size_t room;  // bytes the declared size still allows after buf[op]
};

// Decodes instructions until buf[stop] is reached or passed, or the next
// instruction starts at or after `in_limit` (<= c->in_end; every instruction
// that starts before it has all its bytes before c->in_end, or c->in_end is
// the stream's end); kOk unless the stream is bad.
inline LzfResult DecodeUntil(LzfCursor* c,
                             size_t stop,
                             const uint8_t* in_limit) {
  const uint8_t* ip = c->ip;
  const uint8_t* const in_end = c->in_end;
  uint8_t* const buf = c->buf;
  size_t op = c->op, room = c->room;
  LzfResult result = LzfResult::kOk;
  while (ip < in_limit && op < stop) {
    if (op >= kWindow && static_cast<size_t>(in_end - ip) > kFastInput &&
        room > kMaxInstructionOutput) {
      // Far from both ends: every instruction's bytes are in, its output
      // fits the declared size (room is folded into stop_fast) and every
      // distance is valid (op >= kWindow), so none needs a check; the same
      // instructions as below, with the checks they would pass left out
      // (about a fifth faster on float data).
      const uint8_t* const ip_fast_end = in_end - kFastInput;
      const size_t op_start = op;
      const size_t stop_fast =
          std::min(stop, op + room - kMaxInstructionOutput);
      while (ip < ip_fast_end && op < stop_fast) {
        const size_t ctrl = *ip++;
        if (ctrl < 32) {  // literal run
          std::memcpy(buf + op, ip, 32);
          op += ctrl + 1;
          ip += ctrl + 1;
          continue;
        }
        size_t len = ctrl >> 5;
        if (len == 7) len += *ip++;
        const size_t dist = ((ctrl & 31u) << 8) + *ip++ + 1;
        CopyBackReference(buf + op, dist, len + 2);
        op += len + 2;
      }
      room -= op - op_start;
      continue;
    }
    const size_t ctrl = *ip++;
    if (ctrl < 32) {  // literal run
      const size_t len = ctrl + 1;
      if (len > room) {
        result = LzfResult::kTooLong;
        break;
      }
      const size_t left = static_cast<size_t>(in_end - ip);
      if (left < len) {
        result = LzfResult::kInvalid;
        break;
      }
      if (left >= 32) {
        std::memcpy(buf + op, ip, 32);  // fixed size: two vector moves
      } else {
        std::memcpy(buf + op, ip, len);
      }
      op += len;
      room -= len;
      ip += len;
      continue;
    }
    size_t len = ctrl >> 5;
    if (ip >= in_end) {
      result = LzfResult::kInvalid;
      break;
    }
    if (len == 7) {
      len += *ip++;
      if (ip >= in_end) {
        result = LzfResult::kInvalid;
        break;
      }
    }
    const size_t dist = ((ctrl & 31u) << 8) + *ip++ + 1;
    len += 2;
    if (len > room) {
      result = LzfResult::kTooLong;
      break;
    }
    if (dist > op) {  // buf[0] is the stream's start or kWindow back
      result = LzfResult::kInvalid;
      break;
    }
    CopyBackReference(buf + op, dist, len);
    op += len;
    room -= len;
  }
  c->ip = ip;
  c->op = op;
  c->room = room;
  return result;
}

// Decodes a stream of in_size bytes, which must expand to exactly out_size
// bytes, reading it in chunks of about `input_bytes` (at least 64) through
// read(dst, n), which fills dst with the stream's next n bytes or returns
// false (then the result is kInputStopped). The output goes to
// sink.Consume(offset, data, n) in stream order, in pieces of about
// `piece_bytes`; Consume returns how many of the n bytes it used, at least
// n - 64 (a partial value at the end of a piece is handed again, at the start
// of the next one). The last call ends at out_size and must use every byte.
// *produced: the output length reached (for messages). Memory: one input
// chunk, the 8 KiB window and one piece, whatever the stream's size.
template <typename Sink, typename Read>
LzfResult DecodeLzfStream(uint64_t in_size,
                          uint64_t out_size,
                          size_t piece_bytes,
                          size_t input_bytes,
                          Sink& sink,
                          uint64_t* produced,
                          Read&& read) {
  input_bytes = std::max<size_t>(input_bytes, 64);
  std::vector<uint8_t> buffer(kWindow + piece_bytes + kSlack + 64);
  // The input chunk, after up to kMaxInstructionBytes carried over from the
  // last one (an instruction that chunk cut).
  std::vector<uint8_t> input(kMaxInstructionBytes + input_bytes);
  uint64_t unread = in_size;  // stream bytes not yet read
  LzfCursor c{input.data(), input.data(), buffer.data(), 0, out_size};
  uint64_t base = 0;      // stream offset of buf[0]
  uint64_t consumed = 0;  // stream offset the sink has used up to
  auto hand_out = [&]() {
    const size_t from = static_cast<size_t>(consumed - base);
    consumed += sink.Consume(consumed, c.buf + from, c.op - from);
  };
  LzfResult result = LzfResult::kOk;
  for (;;) {
    size_t left = static_cast<size_t>(c.in_end - c.ip);
    if (unread > 0 && left <= kMaxInstructionBytes) {  // next chunk
      std::memmove(input.data(), c.ip, left);
      const size_t n =
          static_cast<size_t>(std::min<uint64_t>(unread, input_bytes));
      if (!read(input.data() + left, n)) {
        result = LzfResult::kInputStopped;
        break;
      }
      unread -= n;
      c.ip = input.data();
      c.in_end = input.data() + left + n;
      left += n;
    }
    if (left == 0) break;  // the stream's end
    // Before the stream's end, an instruction is decoded only if all its
    // bytes are in this chunk.
    const uint8_t* const in_limit =
        unread == 0 ? c.in_end : c.in_end - kMaxInstructionBytes;
    result = DecodeUntil(&c, kWindow + piece_bytes, in_limit);
    if (result != LzfResult::kOk) break;
    if (c.op < kWindow + piece_bytes) continue;  // the chunk is used up
    hand_out();
    // Keep the back-reference window and whatever the sink did not use.
    size_t keep = c.op >= kWindow ? c.op - kWindow : 0;
    keep = std::min(keep, static_cast<size_t>(consumed - base));
    std::memmove(c.buf, c.buf + keep, c.op - keep);
    base += keep;
    c.op -= keep;
  }
  *produced = base + c.op;
  if (result == LzfResult::kOk && *produced < out_size)
    result = LzfResult::kShort;
  if (result == LzfResult::kOk) hand_out();
  return result;
}

// DecodeLzfStream over in[0, in_size), in memory.
template <typename Sink>
LzfResult DecodeLzf(const uint8_t* in,
                    size_t in_size,
                    uint64_t out_size,
                    size_t piece_bytes,
                    Sink& sink,
                    uint64_t* produced) {
  size_t at = 0;
  return DecodeLzfStream(in_size, out_size, piece_bytes, size_t{64} << 10, sink,
                         produced, [&](uint8_t* dst, size_t n) {
                           std::memcpy(dst, in + at, n);
                           at += n;
                           return true;
                         });
}

}  // namespace lzf_stream
}  // namespace geodrive
