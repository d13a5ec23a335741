#pragma once
// Point cloud files: PLY and PCD (our own readers and writers, no PCL io),
// nuScenes LIDAR_TOP `.pcd.bin` and KITTI velodyne `.bin`. Every failure
// throws InputError naming the file; nothing is printed.
//
// Hostile input: every size a file declares is checked against the bytes that
// follow its header, and against kMaxPointCloudPoints, before anything is
// allocated. ASCII values that do not parse (garbage, too few or too many on a
// line, integers out of range of their declared type) are errors naming the
// line and the token, never zeros or vanished points. Truncated bodies are
// errors.
//
// Non-finite coordinates, one policy for every reader here: a point whose x,
// y or z is NaN or ±inf is an error "point 17 has a non-finite coordinate
// (nan)" (also "+inf", "-inf"; the index counts from 0 in file order). The one
// exception is an organised PCD file (HEIGHT > 1), where PCL writes NaN for
// pixels without a return: there, points with a NaN coordinate are dropped
// (ReadPcd's summary counts them); ±inf is still an error.
//
// Attributes, the same for PLY properties and PCD fields: x y z (float or
// double; required) → positions; `rgb` or `rgba` (4 bytes, packed 0x00RRGGBB
// as PCL does, float or integer) or else `red` `green` `blue` (else
// `diffuse_red`..., else `r` `g` `b`; any numeric type, rounded and clamped
// to 0..255) → colors; `confidence`, `intensity`, `ring` (any numeric type) →
// float attributes; `instance_id` (any numeric type, must be in the int32
// range); `footprint` (any numeric type, finite and >= 0) → footprints, and
// with it `footprint_ux` `footprint_uy` `footprint_uz` `footprint_vx`
// `footprint_vy` `footprint_vz` (all six, finite) → footprint_u / _v, as the
// writers below store capture footprints. Everything else (normals, `alpha`,
// `label`, PCD `_` padding, lists, other PLY elements such as faces) is
// skipped.
//
// Threads: ASCII bodies of 2 MB and more are parsed in chunks on OpenMP's
// threads (OMP_NUM_THREADS; one thread inside a parallel region), with the
// same result and the same first error as one thread. Everything else reads
// on the calling thread.

#include <cstdint>
#include <string>

#include "geometry/point_cloud.h"

namespace geodrive {

// The most points one file may declare (PLY vertices, PCD WIDTH x HEIGHT,
// records of a .bin file).
constexpr uint64_t kMaxPointCloudPoints = uint64_t{1} << 31;

// nuScenes `.pcd.bin`: little-endian float32 x 5 per point (x, y, z, intensity,
// ring), LIDAR_TOP frame (x right, y forward, z up). Fills positions, intensity
// and ring. The file size must be a multiple of 20 bytes.
PointCloud ReadNuscenesLidarBin(const std::string& path);
void WriteNuscenesLidarBin(const std::string& path, const PointCloud& cloud);

// KITTI velodyne `.bin`: float32 x 4 (x, y, z, reflectance), x forward, y left,
// z up. Fills positions and intensity. The file size must be a multiple of 16
// bytes.
PointCloud ReadKittiVelodyneBin(const std::string& path);
// Writes float32 x 4 (intensity 0 where the cloud has none).
void WriteKittiVelodyneBin(const std::string& path, const PointCloud& cloud);

// PLY, formats ascii, binary_little_endian and binary_big_endian; the vertex
// element's scalar properties in any order and of any PLY type (char ... double
// and the int8 ... float64 aliases). ASCII bodies have one element item per
// line (blank lines are ignored). Trailing bytes after the last element of a
// binary file are ignored.
PointCloud ReadPly(const std::string& path);
// Binary little-endian (or ASCII, floats as %.9g, which round-trips float32):
// float x y z, then uchar red green blue, float confidence, int instance_id,
// float intensity, float ring, float footprint, float footprint_ux ...
// footprint_vz for the attributes the cloud has.
void WritePly(const std::string& path,
              const PointCloud& cloud,
              bool binary = true);

// What ReadPcd saw besides the points.
struct PcdReadSummary {
  uint64_t width = 0;
  uint64_t height = 0;
  std::string data;  // "ascii", "binary" or "binary_compressed"
  // Points with a NaN coordinate dropped (organised files only, see above).
  uint64_t dropped_nan_points = 0;
};

// PCD (PCL's format), VERSION 0.5 to 0.7 headers, DATA ascii, binary or
// binary_compressed (LZF, fields stored one after another). Fields with COUNT
// > 1 are skipped (x, y and z must have COUNT 1). VIEWPOINT is checked but not
// applied. Trailing bytes after binary data are ignored (older PCL pads).
PointCloud ReadPcd(const std::string& path);
PointCloud ReadPcd(const std::string& path, PcdReadSummary* summary);
// The files PCL 1.13 writes (byte for byte, less PCL's trailing zero padding
// of binary files): VERSION 0.7, VIEWPOINT 0 0 0 1 0 0 0, fields x y z (F 4),
// rgb (packed 0x00RRGGBB; F 4 in binary, U 4 and an integer in ASCII),
// intensity (F 4), confidence (F 4), instance_id (I 4), ring (F 4), then
// footprint and footprint_ux ... footprint_vz (F 4) for the attributes the
// cloud has; DATA binary, or ascii (floats as %.9g). An empty
// cloud is written as DATA ascii. Deterministic and atomic.
void WritePcd(const std::string& path,
              const PointCloud& cloud,
              bool binary = true);

// Dispatch on extension (case-insensitive): .ply, .pcd, .pcd.bin (nuScenes),
// .bin (KITTI). Writes are atomic (temporary file + rename).
PointCloud ReadPointCloud(const std::string& path);
void WritePointCloud(const std::string& path, const PointCloud& cloud);

}  // namespace geodrive
