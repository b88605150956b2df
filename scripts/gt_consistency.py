#!/usr/bin/env python3
"""How far the images themselves put a ground-truth homography's corners.

For each pair of a manifest (lines `img1 img2 H`, as eval_pairs.py reads),
the ground-truth homography is refined photometrically (OpenCV
findTransformECC, MOTION_HOMOGRAPHY, started AT the truth) and the script
prints how far the refined homography moves image 1's four corners from where
the truth puts them: the corner-error metric of eval_pairs.py applied to the
image-aligned optimum. Where that is several pixels, a matcher's corner error
below it measures the ground truth's own precision, not the matcher's.

A second, independent witness: OpenCV SIFT correspondences (ratio 0.8, RANSAC
at 3 px, nothing of mvkp), whose inliers' median transfer error in image 2 is
printed under the truth and under the ECC optimum. The homography the images
support has the smaller one.

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


def sift_inliers(im1, im2):
    """SIFT + ratio test + RANSAC (3 px) inliers: (points in image 1, points in image 2)."""
    sift = cv2.SIFT_create()
    k1, d1 = sift.detectAndCompute(im1, None)
    k2, d2 = sift.detectAndCompute(im2, None)
    if d1 is None or d2 is None or len(k1) < 4 or len(k2) < 4:
        return None
    good = [m[0] for m in cv2.BFMatcher(cv2.NORM_L2).knnMatch(d1, d2, k=2) if len(m) == 2 and m[0].distance < 0.8 * m[1].distance]
    if len(good) < 8:
        return None
    p1 = np.float64([k1[m.queryIdx].pt for m in good])
    p2 = np.float64([k2[m.trainIdx].pt for m in good])
    _, mask = cv2.findHomography(p1, p2, cv2.RANSAC, 3.0)
    if mask is None:
        return None
    keep = mask.ravel() > 0
    if keep.sum() < 20:  # SIFT did not find the pair (graf 1->5, 1->6): no witness
        return None
    return p1[keep], p2[keep]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('manifest')
    ap.add_argument('--blur', type=int, default=5, help='ECC Gaussian filter size (odd)')
    ap.add_argument('--iters', type=int, default=100)
    a = ap.parse_args()
    print('pair                                   corner shift of the ECC optimum from the truth (px): mean [4 corners]  ECC'
          '  | SIFT inliers: n, median transfer error (px) under the truth / under the ECC optimum')
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
        inl = sift_inliers(im1, im2)
        witness = '  | SIFT finds too few inliers'
        if inl is not None:
            e_truth = np.median(np.linalg.norm(project(H, inl[0]) - inl[1], axis=1))
            e_ecc = np.median(np.linalg.norm(project(He, inl[0]) - inl[1], axis=1))
            witness = f'  | {len(inl[0]):4d}  {e_truth:5.2f} / {e_ecc:5.2f}'
        print(f'{name:38s} {d.mean():6.2f}  {np.round(d, 1)}  {cc:.3f}{witness}')


if __name__ == '__main__':
    main()
