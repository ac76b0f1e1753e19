"""An MP4 written by the recording writer plays in OpenCV's FFmpeg backend.

Usage: synth_mp4_play.py VIDEO.mp4 FRAMES_DIR COUNT
Decodes VIDEO.mp4 with cv2.VideoCapture and compares every frame with
FRAMES_DIR/NNNNNN.png (the frames that were encoded): same count, same size,
PSNR above MIN_PSNR_DB. Exit status 0 = pass.
"""
import sys

import cv2
import numpy as np

MIN_PSNR_DB = 30.0


def main():
    video, frames_dir, count = sys.argv[1], sys.argv[2], int(sys.argv[3])
    cap = cv2.VideoCapture(video)
    if not cap.isOpened():
        raise SystemExit(f"cv2.VideoCapture cannot open {video}")
    worst = float("inf")
    n = 0
    while True:
        ok, frame = cap.read()
        if not ok:
            break
        ref = cv2.imread(f"{frames_dir}/{n:06d}.png")
        if ref is None or ref.shape != frame.shape:
            raise SystemExit(f"frame {n}: shape {frame.shape} vs reference {None if ref is None else ref.shape}")
        mse = np.mean((frame.astype(np.float64) - ref.astype(np.float64)) ** 2)
        worst = min(worst, 10 * np.log10(255.0 ** 2 / max(mse, 1e-12)))
        n += 1
    print(f"cv2.VideoCapture read {n} frames of {video}, worst PSNR {worst:.1f} dB")
    if n != count:
        raise SystemExit(f"FAIL: {n} frames decoded, {count} written")
    if worst < MIN_PSNR_DB:
        raise SystemExit(f"FAIL: worst PSNR {worst:.1f} dB < {MIN_PSNR_DB}")


if __name__ == "__main__":
    main()
