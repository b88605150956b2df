#!/usr/bin/env python3
"""How far the images themselves put a ground-truth homography's corners.

For each pair of a manifest (lines `img1 img2 H`, as eval_pairs.py reads),
the ground-truth homography is refined photometrically (OpenCV
findTransformECC, MOTION_HOMOGRAPHY, started AT the truth) and the script
prints how far the refined homography moves image 1's four corners from where
the truth puts them: the corner-error metric of eval_pairs.py applied to the
image-aligned optimum. Where that is several pixels, a matcher's corner error
below it measures the ground truth's own precision, not the matcher's.

    scripts/gt_consistency.py MANIFEST [--blur 5] [--iters 100]
"""
import argparse
import sys

import cv2
import numpy as np


def load_h(path):
    if path.endswith(('.xml', '.yml', '.yaml')):
        fs = cv2.FileStorage(path, cv2.FILE_STORAGE_READ)
        node = fs.getFirstTopLevelNode()
        return node.mat().astype(np.float64)
    return np.loadtxt(path).reshape(3, 3)


def project(H, pts):
    x = np.c_[pts, np.ones(len(pts))] @ H.T
    return x[:, :2] / x[:, 2:]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('manifest')
    ap.add_argument('--blur', type=int, default=5, help='ECC Gaussian filter size (odd)')
    ap.add_argument('--iters', type=int, default=100)
    a = ap.parse_args()
    print('pair                                   corner shift of the ECC optimum from the truth (px): mean [4 corners]  ECC')
    for line in open(a.manifest):
        f = line.split()
        if len(f) < 3 or f[2] == 'none':
            continue
        im1 = cv2.imread(f[0], cv2.IMREAD_GRAYSCALE)
        im2 = cv2.imread(f[1], cv2.IMREAD_GRAYSCALE)
        if im1 is None or im2 is None:
            sys.exit(f'gt_consistency: cannot read {f[0]} or {f[1]}')
        H = load_h(f[2])
        h, w = im1.shape
        corners = np.array([[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]], np.float64)
        # ECC warps image 2's pixels into image 1: start from the truth's inverse.
        W = np.linalg.inv(H)
        W = (W / W[2, 2]).astype(np.float32)
        try:
            cc, W = cv2.findTransformECC(im2.astype(np.float32), im1.astype(np.float32), W, cv2.MOTION_HOMOGRAPHY,
                                         (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, a.iters, 1e-6), None,
                                         a.blur)
        except cv2.error as e:
            print(f'{f[0]} -> {f[1]}: ECC did not converge ({e.err})')
            continue
        He = np.linalg.inv(W.astype(np.float64))
        He /= He[2, 2]
        d = np.linalg.norm(project(He, corners) - project(H, corners), axis=1)
        name = '/'.join(f[0].split('/')[-2:]) + ' -> ' + f[1].split('/')[-1]
        print(f'{name:38s} {d.mean():6.2f}  {np.round(d, 1)}  {cc:.3f}')


if __name__ == '__main__':
    main()
