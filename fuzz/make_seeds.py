#!/usr/bin/python3
"""Writes the seed corpora of the fuzz targets into fuzz/corpus/<target>/.

Run once with Debian's /usr/bin/python3 (numpy, python3-opencv) from the
repository root, with a built `geodrive` for the nuScenes tables:
    /usr/bin/python3 fuzz/make_seeds.py build/apps/geodrive
    /usr/bin/python3 fuzz/make_seeds.py --only npz      # one target's seeds
The seeds are small valid (and a few nearly valid) files of every layout each
reader accepts; they are committed, so CI does not run this script.
"""
import json
import os
import shutil
import struct
import subprocess
import sys
import tempfile

import cv2
import numpy as np

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "corpus")


def out(target, name, data):
    d = os.path.join(ROOT, target)
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, name), "wb") as f:
        f.write(data if isinstance(data, bytes) else data.encode())


def npy_bytes(array, **kw):
    import io
    b = io.BytesIO()
    np.lib.format.write_array(b, array, **kw)
    return b.getvalue()


def npy_seeds():
    rng = np.random.default_rng(7)
    # fuzz_npy's finding (docs/RELIABILITY.md): a zero axis after axes whose
    # product passes 2^63; the header exactly as the fuzzer wrote it.
    head = (b"{'descr': '<f8', 'fortran_order': False, 'shape': (4, 32 ,64, 2, "
            b"364, 32 ,64, 2, 366,66, 2, 366632 ,00000, 34, 6), }  ")
    out("npy", "regression-empty-huge-axes.npy",
        b"\x93NUMPY\x01\x00" + len(head).to_bytes(2, "little") + head + b"  ")
    out("npy", "f4_2d.npy", npy_bytes(rng.random((4, 6), dtype=np.float32)))
    out("npy", "f8_3d.npy", npy_bytes(rng.random((3, 2, 3))))
    out("npy", "u1.npy", npy_bytes(np.arange(12, dtype=np.uint8).reshape(3, 4)))
    out("npy", "bool.npy", npy_bytes(np.array([True, False, True])))
    out("npy", "i8_fortran.npy",
        npy_bytes(np.asfortranarray(np.arange(6, dtype=np.int64).reshape(2, 3))))
    out("npy", "be_f4.npy", npy_bytes(np.arange(5, dtype=">f4")))
    out("npy", "v2.npy", npy_bytes(np.zeros((2, 2), np.float32), version=(2, 0)))
    out("npy", "u2.npy", npy_bytes(np.arange(4, dtype=np.uint16)))
    out("npy", "i4_scalar.npy", npy_bytes(np.array(3, dtype=np.int32)))


PTS = np.array([[0.5, -1.25, 3.0], [1.0, 2.0, 4.5], [-0.25, 0.75, 9.0]],
               np.float32)
RGB = np.array([[255, 0, 10], [0, 128, 255], [7, 8, 9]], np.uint8)


def npz_seeds():
    import io
    rng = np.random.default_rng(8)
    depth = rng.random((2, 3, 4), dtype=np.float32)
    for name, save in (("stored.npz", np.savez), ("deflated.npz", np.savez_compressed)):
        b = io.BytesIO()
        save(b, depth=depth, depth16=depth.astype(np.float16),
             cam_c2w=np.eye(4)[None].repeat(2, 0), images=np.zeros((2, 3, 4, 3), np.uint8))
        out("npz", name, b.getvalue())


def npz_zip_seeds():
    """Zip-level layouts: stored, deflated, many members, a string member, a
    bzip2 member (a small bomb), a member declaring more than it holds."""
    import io
    import zipfile
    a = np.arange(12, dtype=np.float32).reshape(3, 4)
    for name, save in (("stored.npz", np.savez), ("deflated.npz", np.savez_compressed)):
        b = io.BytesIO()
        save(b, depth=a, units=np.array("metres"))
        out("npz_zip", name, b.getvalue())
    b = io.BytesIO()
    np.savez(b, **{"m%d" % i: np.zeros(1, np.uint8) for i in range(40)})
    out("npz_zip", "many.npz", b.getvalue())
    b = io.BytesIO()
    with zipfile.ZipFile(b, "w", zipfile.ZIP_BZIP2) as z:
        z.writestr("zeros.npy", npy_bytes(np.zeros(1 << 18, np.float32)))
    out("npz_zip", "bzip2_bomb.npz", b.getvalue())
    b = io.BytesIO()
    with zipfile.ZipFile(b, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("zeros.npy", npy_bytes(np.zeros(1 << 16, np.float32)))
    out("npz_zip", "deflate_ratio.npz", b.getvalue())
    data = bytearray(b.getvalue())
    for sig, at in ((b"PK\x03\x04", 22), (b"PK\x01\x02", 24)):
        i = data.find(sig)
        data[i + at:i + at + 4] = struct.pack("<I", 3 << 30)
    out("npz_zip", "declares_3gib.npz", bytes(data))


def exr_header_seeds():
    """Scanline files (none, ZIPS, ZIP), a tiled and a multi-part header: the
    attributes OpenEXR requires, channel Z or X, Y, Z."""
    import zlib

    def attr(name, typ, value):
        return name.encode() + b"\0" + typ.encode() + b"\0" + struct.pack("<i", len(value)) + value

    def chlist(names):
        return b"".join(n.encode() + b"\0" + struct.pack("<i4xii", 2, 1, 1) for n in names) + b"\0"

    def header(w, h, comp, names, extra=b""):
        box = struct.pack("<iiii", 0, 0, w - 1, h - 1)
        return (attr("channels", "chlist", chlist(names)) +
                attr("compression", "compression", bytes([comp])) +
                attr("dataWindow", "box2i", box) + attr("displayWindow", "box2i", box) +
                attr("lineOrder", "lineOrder", b"\0") +
                attr("pixelAspectRatio", "float", struct.pack("<f", 1)) +
                attr("screenWindowCenter", "v2f", struct.pack("<ff", 0, 0)) +
                attr("screenWindowWidth", "float", struct.pack("<f", 1)) + extra)

    def scanline(w, h, names, comp):
        head = struct.pack("<ii", 20000630, 2) + header(w, h, comp, names) + b"\0"
        rows = []
        for y in range(h):
            raw = b"".join(struct.pack("<%df" % w, *[1.0 + y + x for x in range(w)]) for _ in names)
            if comp == 2:  # ZIPS: byte split + predictor, then zlib
                t = bytearray(len(raw))
                t[0::1] = raw
                half = (len(raw) + 1) // 2
                t[:half] = raw[0::2]
                t[half:] = raw[1::2]
                p = t[0]
                for i in range(1, len(t)):
                    d = (t[i] - p + 128 + 256) & 0xFF
                    p = t[i]
                    t[i] = d
                packed = zlib.compress(bytes(t))
                raw = packed if len(packed) < len(raw) else raw
            rows.append(struct.pack("<ii", y, len(raw)) + raw)
        offsets, at = [], len(head) + 8 * h
        for r in rows:
            offsets.append(at)
            at += len(r)
        return head + b"".join(struct.pack("<Q", o) for o in offsets) + b"".join(rows)

    out("exr_header", "z_none.exr", scanline(4, 3, ["Z"], 0))
    out("exr_header", "xyz_none.exr", scanline(3, 2, ["X", "Y", "Z"], 0))
    out("exr_header", "z_zips.exr", scanline(8, 2, ["Z"], 2))
    tiles = attr("tiles", "tiledesc", struct.pack("<IIB", 2, 2, 0))
    out("exr_header", "tiled_header.exr", struct.pack("<ii", 20000630, 2 | 0x200) +
        header(4, 4, 0, ["Z"], tiles) + b"\0" + bytes(64))
    part = attr("name", "string", b"p") + attr("type", "string", b"scanlineimage") + \
        attr("chunkCount", "int", struct.pack("<i", 2))
    out("exr_header", "multipart_header.exr", struct.pack("<ii", 20000630, 2 | 0x1000) +
        header(2, 2, 0, ["Z"], part) + b"\0\0" + bytes(64))
    out("exr_header", "huge_window.exr", struct.pack("<ii", 20000630, 2) +
        header(16384, 16384, 0, ["Z"]) + b"\0" + bytes(4096))


def reconstruction_seeds():
    """Each npz format's layout, small (2 frames of 3x4)."""
    import io
    rng = np.random.default_rng(9)
    depth = 1 + rng.random((2, 3, 4), dtype=np.float32)
    c2w = np.eye(4)[None].repeat(2, 0)
    c2w[1, 2, 3] = 0.5
    w2c = np.linalg.inv(c2w)
    K = np.array([[4.0, 0, 2], [0, 4.0, 1.5], [0, 0, 1]], np.float32)
    layouts = {
        "vggt_predictions.npz": (np.savez, dict(
            extrinsic=w2c[:, :3].astype(np.float32), intrinsic=K[None].repeat(2, 0),
            depth=depth[..., None], depth_conf=1 + depth,
            images=rng.random((2, 3, 3, 4), dtype=np.float32))),
        "da3_results.npz": (np.savez_compressed, dict(
            image=np.zeros((2, 3, 4, 3), np.uint8), depth=depth,
            conf=np.round(1 + depth, 2), extrinsics=w2c.astype(np.float32),
            intrinsics=K[None].repeat(2, 0))),
        "megasam_sgd_cvd_hr.npz": (np.savez, dict(
            images=np.zeros((2, 3, 4, 3), np.uint8), depths=depth.astype(np.float16),
            intrinsic=K, cam_c2w=c2w.astype(np.float32))),
        "generic.npz": (np.savez, dict(
            depth=depth, intrinsics=K, cam_c2w=c2w, conf=depth - 1,
            conf_scale="unit", units="metres",
            dynamic_mask=np.zeros((2, 3, 4), np.uint8))),
    }
    for name, (save, arrays) in layouts.items():
        b = io.BytesIO()
        save(b, **arrays)
        out("reconstruction", name, b.getvalue())


def ply_seeds():
    head = "ply\nformat {}\ncomment seed\nelement vertex 3\n" \
           "property float x\nproperty float y\nproperty float z\n" \
           "property uchar red\nproperty uchar green\nproperty uchar blue\n"
    body = "".join("%g %g %g %d %d %d\n" % (*p, *c) for p, c in zip(PTS, RGB))
    out("ply", "ascii.ply", head.format("ascii 1.0") + "end_header\n" + body)
    for fmt, e in (("binary_little_endian 1.0", "<"), ("binary_big_endian 1.0", ">")):
        data = b"".join(struct.pack(e + "fffBBB", *p, *c) for p, c in zip(PTS, RGB))
        name = "le.ply" if e == "<" else "be.ply"
        out("ply", name, (head.format(fmt) + "end_header\n").encode() + data)
    # double coordinates, shuffled properties, extra scalar, a face element.
    head2 = ("ply\nformat binary_little_endian 1.0\nelement vertex 3\n"
             "property uchar red\nproperty double z\nproperty float confidence\n"
             "property double x\nproperty uchar green\nproperty double y\n"
             "property uchar blue\nproperty int instance_id\n"
             "element face 1\nproperty list uchar int vertex_indices\n"
             "end_header\n")
    data = b"".join(struct.pack("<BdfdBdBi", c[0], p[2], 0.5, p[0], c[1], p[1],
                                c[2], i) for i, (p, c) in enumerate(zip(PTS, RGB)))
    data += struct.pack("<Biii", 3, 0, 1, 2)
    out("ply", "mixed.ply", head2.encode() + data)
    # Capture footprints with their axes, as WritePly stores them.
    head3 = ("ply\nformat binary_little_endian 1.0\nelement vertex 3\n"
             "property float x\nproperty float y\nproperty float z\n"
             "property float footprint\n" +
             "".join("property float footprint_%s%s\n" % (a, c)
                     for a in "uv" for c in "xyz") + "end_header\n")
    data = b"".join(struct.pack("<10f", *p, 0.01 * (i + 1), 0.01, 0, 0, 0, 0.01, 0)
                    for i, p in enumerate(PTS))
    out("ply", "footprint.ply", head3.encode() + data)


def lzf_literals(raw):
    """LZF stream made of literal runs only (valid input for lzf_decompress)."""
    o = bytearray()
    for i in range(0, len(raw), 32):
        chunk = raw[i:i + 32]
        o.append(len(chunk) - 1)
        o += chunk
    return bytes(o)


def pcd_seeds():
    def header(fields, size, typ, count, n, data):
        return ("# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n"
                "FIELDS %s\nSIZE %s\nTYPE %s\nCOUNT %s\nWIDTH %d\nHEIGHT 1\n"
                "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS %d\nDATA %s\n"
                % (fields, size, typ, count, n, n, data))
    rgb = [struct.unpack("<f", struct.pack("<I", (int(c[0]) << 16) |
                                           (int(c[1]) << 8) | int(c[2])))[0]
           for c in RGB]
    body = "".join("%g %g %g %.9g 0.5\n" % (*p, r) for p, r in zip(PTS, rgb))
    out("pcd", "ascii.pcd",
        header("x y z rgb intensity", "4 4 4 4 4", "F F F F F", "1 1 1 1 1", 3,
               "ascii") + body)
    recs = b"".join(struct.pack("<ffffI", *p, r, 7) for p, r in zip(PTS, rgb))
    out("pcd", "binary.pcd",
        header("x y z rgb ring", "4 4 4 4 4", "F F F F U", "1 1 1 1 1", 3,
               "binary").encode() + recs)
    # binary_compressed: field-major (SoA) data, then LZF.
    soa = b"".join(struct.pack("<3f", *PTS[:, k]) for k in range(3))
    soa += struct.pack("<3f", *rgb)
    comp = lzf_literals(soa)
    out("pcd", "compressed.pcd",
        header("x y z rgb", "4 4 4 4", "F F F F", "1 1 1 1", 3,
               "binary_compressed").encode() +
        struct.pack("<II", len(comp), len(soa)) + comp)


def bin_seeds():
    five = np.array([[1, 2, 3, 0.5, 7], [4, 5, 6, 1.0, 31]], np.float32)
    out("lidar_bin", "nuscenes.pcd.bin", five.tobytes())
    out("lidar_bin", "kitti.bin", five[:, :4].tobytes())


def text_seeds():
    out("trajectory_text", "pred_traj.txt",
        "0.0 0 0 0 1 0 0 0\n0.1 0.1 0 0.5 0.99875 0 0.04998 0\n"
        "0.2 0.2 0.01 1.0 0.995 0 0.0998 0\n")
    out("trajectory_text", "tum.txt",
        "# timestamp tx ty tz qx qy qz qw\n1.0 0 0 0 0 0 0 1\n"
        "1.5 0.1 0.2 0.3 0 0.0499792 0 0.99875\n")
    out("trajectory_text", "kitti_poses.txt",
        "1 0 0 0 0 1 0 0 0 0 1 0\n9.999978e-01 5.272628e-04 -2.066935e-03 -4.690294e-02 "
        "-5.296506e-04 9.999992e-01 -1.154865e-03 -2.839928e-02 2.066324e-03 "
        "1.155958e-03 9.999971e-01 8.586941e-01\n")
    out("trajectory_text", "colmap_images.txt",
        "# Image list with two lines of data per image:\n"
        "1 1 0 0 0 0 0 0 1 frame_0000.jpg\n10.5 20.5 -1\n"
        "2 0.99875 0 0.0499792 0 0.1 0 -1 1 frame_0001.jpg\n\n")
    out("trajectory_text", "intrinsics.txt",
        "256.0 0 256.0 0 256.0 144.0 0 0 1\n256.0 0 256.0 0 256.0 144.0 0 0 1\n")


def json_seeds():
    traj = {"format": "geodrive-trajectory", "version": 1,
            "convention": "world_from_cam", "units": "metres",
            "camera": {"fx": 500.0, "fy": 500.0, "cx": 359.5, "cy": 239.5,
                       "width": 720, "height": 480},
            "frames": [{"t": 0.0, "position": [0, 0, 0],
                        "quaternion_wxyz": [1, 0, 0, 0]},
                       {"t": 0.1, "position": [0, 0, 1],
                        "quaternion_wxyz": [1, 0, 0, 0]}]}
    out("trajectory_json", "trajectory.json", json.dumps(traj, indent=1))
    boxes = {"format": "geodrive-boxes", "version": 1, "image_width": 1600,
             "image_height": 900, "num_frames": 2, "units": "metres",
             "instances": [{"id": "car-1", "category": "vehicle.car",
                            "frames": [{"frame": 0, "box_2d": [100, 200, 300, 400],
                                        "box_3d": {"center": [0, 0, 10],
                                                   "size": [1.8, 4.5, 1.5],
                                                   "rotation_wxyz": [1, 0, 0, 0]},
                                        "visibility": 0.8},
                                       {"frame": 1, "box_2d": [110, 200, 310, 400]}]}]}
    out("boxes_json", "boxes.json", json.dumps(boxes, indent=1))


def image_seeds():
    rng = np.random.default_rng(3)
    img = (rng.random((24, 32, 3)) * 255).astype(np.uint8)
    out("image", "rgb.png", cv2.imencode(".png", img)[1].tobytes())
    out("image", "gray16.png",
        cv2.imencode(".png", (rng.random((8, 8)) * 65535).astype(np.uint16))[1].tobytes())
    out("image", "rgba.png",
        cv2.imencode(".png", np.dstack([img, img[:, :, :1]]))[1].tobytes())
    out("image", "q90.jpg", cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 90])[1].tobytes())
    out("image", "gray.jpg", cv2.imencode(".jpg", img[:, :, 0])[1].tobytes())
    out("image", "progressive.jpg",
        cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_PROGRESSIVE, 1])[1].tobytes())


def safetensors_seeds():
    def st(tensors, metadata=None):
        header, buf = {}, b""
        for name, dtype, shape, data in tensors:
            header[name] = {"dtype": dtype, "shape": shape,
                            "data_offsets": [len(buf), len(buf) + len(data)]}
            buf += data
        if metadata:
            header["__metadata__"] = metadata
        h = json.dumps(header).encode()
        h += b" " * (-(8 + len(h)) % 8)
        return struct.pack("<Q", len(h)) + h + buf
    out("safetensors", "f32.safetensors",
        st([("w", "F32", [2, 2], np.arange(4, dtype="<f4").tobytes())],
           {"format": "pt"}))
    out("safetensors", "mixed.safetensors",
        st([("a", "BF16", [3], b"\x80\x3f" * 3),
            ("b", "I64", [], struct.pack("<q", -5)),
            ("c", "BOOL", [2], b"\x01\x00"),
            ("d", "F16", [0, 4], b"")]))


def nuscenes_seeds(geodrive):
    tables = ["attribute", "calibrated_sensor", "category", "ego_pose",
              "instance", "log", "map", "sample", "sample_annotation",
              "sample_data", "scene", "sensor", "visibility"]
    tmp = tempfile.mkdtemp()
    try:
        subprocess.run([geodrive, "synth", "--out", tmp, "--scenes", "1",
                        "--duration", "1", "--tables-only"], check=True,
                       stdout=subprocess.DEVNULL)
        for i, t in enumerate(tables):
            with open(os.path.join(tmp, "v1.0-mini", t + ".json"), "rb") as f:
                out("nuscenes_tables", "%02d_%s" % (i, t), bytes([i]) + f.read())
    finally:
        shutil.rmtree(tmp)


if __name__ == "__main__":
    if len(sys.argv) > 2 and sys.argv[1] == "--only":
        globals()[sys.argv[2] + "_seeds"]()
        sys.exit(0)
    npy_seeds()
    npz_seeds()
    npz_zip_seeds()
    exr_header_seeds()
    reconstruction_seeds()
    ply_seeds()
    pcd_seeds()
    bin_seeds()
    text_seeds()
    json_seeds()
    image_seeds()
    safetensors_seeds()
    if len(sys.argv) > 1:
        nuscenes_seeds(sys.argv[1])
