"""OpenCV's own calibration of its chessboard photographs, the reference of
tests/photographs.rs: python3 bench/opencv_calibrate.py target/photographs/opencv

Debian 12's python3-opencv (OpenCV 4.6, as rmvp links), the pictures read as grey by OpenCV,
corners by findChessboardCorners (default flags) refined over rmvp's 5x5 window, and
calibrateCamera with rmvp's default model (k1, k2; no tangential terms, no k3). The principal
point printed is in OpenCV's pixel convention (rmvp's is half a pixel more).
"""
import glob
import sys

import cv2
import numpy as np

files = sorted(glob.glob(sys.argv[1] + "/left*.jpg"))
board = np.zeros((54, 3), np.float32)
board[:, :2] = np.mgrid[0:9, 0:6].T.reshape(-1, 2) * 25.0
objects, pixels = [], []
for name in files:
    grey = cv2.imread(name, cv2.IMREAD_GRAYSCALE)
    found, corners = cv2.findChessboardCorners(grey, (9, 6), None)
    if found:
        criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 50, 1e-4)
        pixels.append(cv2.cornerSubPix(grey, corners, (5, 5), (-1, -1), criteria))
        objects.append(board)
flags = cv2.CALIB_FIX_K3 | cv2.CALIB_ZERO_TANGENT_DIST
rms, k, _, _, _ = cv2.calibrateCamera(objects, pixels, grey.shape[::-1], None, None, flags=flags)
print(f"{len(objects)} images: RMS {rms:.5f} px, fx {k[0, 0]:.3f} fy {k[1, 1]:.3f} cx {k[0, 2]:.3f} cy {k[1, 2]:.3f}")
