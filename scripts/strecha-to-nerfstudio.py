#!/usr/bin/env python3
"""Makes a Strecha / EPFL multi-view scene (one `.camera` text file per image) readable as a
nerfstudio scene, for training: OUT/transforms.json beside a link to the scene's image folder.

The four Strecha captures of ../shared/data/realtrain (PROVENANCE.md there: the files' layout)
are read by no scene reader; their cameras are exact (registered to a laser scan), so they are
worth having as training data. A `.camera` file holds 9 lines: K (3 rows), radial distortion (3
values), R (3 rows, camera-to-world, OpenCV axes: x right, y down, z forward), the camera centre C,
and the image size K belongs to. Nerfstudio wants camera-to-world in OpenGL axes (y up, z back)
and pixel-centre-at-half intrinsics for the images it reads, so the images' downscale is applied
to K (cx' = (cx + 0.5) / s).

Only Python's standard library. Example:
  scripts/strecha-to-nerfstudio.py ../shared/data/realtrain/strecha_fountain_P11 runs/strecha/fountain
(scripts/device/prepare.sh makes the four with --copy-images for the GPU continuation.)
"""
import argparse
import json
import os
import shutil
import sys
from pathlib import Path


def fail(message):
    sys.exit(f"strecha-to-nerfstudio: {message}")


def read_camera(path):
    try:
        rows = [line.split() for line in path.read_text().splitlines() if line.strip()]
        values = [[float(v) for v in row] for row in rows]
    except (OSError, ValueError) as e:
        fail(f"{path}: {e}")
    if len(values) != 9 or [len(r) for r in values] != [3, 3, 3, 3, 3, 3, 3, 3, 2]:
        fail(f"{path}: expected 9 lines (K, distortion, R, centre, size), got {[len(r) for r in values]} numbers a line")
    K, distortion, R, centre, size = values[0:3], values[3], values[4:7], values[7], values[8]
    if any(d != 0 for d in distortion):
        fail(f"{path}: radial distortion {distortion} is not supported (every Strecha scene here has none)")
    return K, R, centre, size


def frame(image, camera_file):
    K, R, C, (full_w, full_h) = read_camera(camera_file)
    try:
        size = jpeg_size(image.read_bytes())
    except OSError as e:
        fail(f"{image}: {e}")
    if size is None:
        fail(f"{image}: not a JPEG whose size could be read")
    w, h = size
    sx, sy = w / full_w, h / full_h
    if abs(sx - sy) > 1e-3 * sx:
        fail(f"{image}: {w}x{h} is not a uniform downscale of {full_w:g}x{full_h:g}")
    # OpenCV axes to OpenGL axes: the rotation's y and z columns change sign.
    c2w = [[R[r][0], -R[r][1], -R[r][2], C[r]] for r in range(3)] + [[0, 0, 0, 1]]
    return {
        "file_path": f"{image.parent.name}/{image.name}",
        "transform_matrix": c2w,
        "w": w, "h": h,
        "fl_x": K[0][0] * sx, "fl_y": K[1][1] * sy,
        "cx": (K[0][2] + 0.5) * sx, "cy": (K[1][2] + 0.5) * sy,
    }


def jpeg_size(data):
    """Width and height from a JPEG's first start-of-frame marker, or None."""
    if data[:2] != b"\xff\xd8":
        return None
    i = 2
    while i + 9 < len(data):
        if data[i] != 0xFF:
            return None
        marker, length = data[i + 1], int.from_bytes(data[i + 2:i + 4], "big")
        if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):  # a start of frame, any coding
            return int.from_bytes(data[i + 7:i + 9], "big"), int.from_bytes(data[i + 5:i + 7], "big")
        i += 2 + length
    return None


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scene", type=Path, help="a Strecha scene: gt_dense_cameras/ and an image folder")
    parser.add_argument("out", type=Path, help="folder to write transforms.json and the image folder's link into")
    parser.add_argument("--images", default=None, help="image folder of the scene (default: the one images* folder)")
    parser.add_argument("--copy-images", action="store_true",
                        help="copy the images instead of linking their folder (for a folder that travels, e.g. to a GPU machine)")
    args = parser.parse_args()
    cameras = args.scene / "gt_dense_cameras"
    if not cameras.is_dir():
        fail(f"{cameras}: no such folder (a Strecha scene has one .camera file per image there)")
    folders = [args.images] if args.images else sorted(p.name for p in args.scene.glob("images*") if p.is_dir())
    if len(folders) != 1:
        fail(f"{args.scene}: give --images, one of {folders}" if folders else f"{args.scene}: no images* folder")
    images = args.scene / folders[0]
    frames = []
    for image in sorted(images.glob("*.jpg")):
        camera_file = cameras / f"{image.name}.camera"
        if not camera_file.is_file():
            fail(f"{camera_file}: missing (every image needs its .camera file)")
        frames.append(frame(image, camera_file))
    if not frames:
        fail(f"{images}: no .jpg images")
    args.out.mkdir(parents=True, exist_ok=True)
    link = args.out / images.name
    if link.is_symlink():
        link.unlink()
    elif link.is_dir():
        shutil.rmtree(link)
    if args.copy_images:
        shutil.copytree(images, link, copy_function=shutil.copyfile)
        os.chmod(link, 0o755)  # the source's folder may be read-only; a later run replaces this one
    else:
        os.symlink(images.resolve(), link)
    tmp = args.out / "transforms.json.tmp"
    tmp.write_text(json.dumps({"camera_model": "OPENCV", "frames": frames}, indent=1))
    os.replace(tmp, args.out / "transforms.json")
    print(f"{args.out / 'transforms.json'}: {len(frames)} frames from {args.scene}")


if __name__ == "__main__":
    main()
