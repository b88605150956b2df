// Consumer of an installed mvkp: load an image, train on the prepared target,
// make one synthetic scene with known geometry, match it, and compare the found
// homography with the true one by the mean distance of the 4 target corners.
//
// Usage: consumer IMAGE. Exit 0 only if the target is found with a corner error
// below 5 px; otherwise prints why and exits 1.
#include <array>
#include <cmath>
#include <cstdio>
#include <exception>

#include <opencv2/core.hpp>

#include "mvkp/core/image_io.h"
#include "mvkp/match/matcher.h"
#include "mvkp/synth/synth.h"
#include "mvkp/train/trainer.h"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s IMAGE\n", argv[0]);
    return 1;
  }
  try {
    const cv::Mat image = mvkp::LoadImageGray(argv[1]);
    const cv::Mat target = mvkp::PrepareTarget(image, 320);

    mvkp::TrainOptions train_options;
    train_options.views = 30;
    const mvkp::Model model = mvkp::Train(target, train_options);

    const mvkp::SceneView scene = mvkp::MakeSceneView(target, mvkp::SceneOptions{}, 5);

    const mvkp::Matcher matcher(model);
    const mvkp::MatchResult result = matcher.Match(scene.image);
    std::printf("target %dx%d, %zu locations, %d keypoints, %zu matches, %d inliers\n", target.cols,
                target.rows, model.locations.size(), result.keypoints, result.matches.size(),
                result.inliers);
    if (!result.found) {
      std::printf("FAIL: target not found in the synthetic scene\n");
      return 1;
    }

    const double error = mvkp::MeanCornerError(result.homography, scene.H, target.size());
    if (!std::isfinite(error) || error >= 5.0) {
      std::printf("FAIL: mean corner error %.3f px (want < 5)\n", error);
      return 1;
    }
    std::printf("ok: found, mean corner error %.3f px\n", error);
    return 0;
  } catch (const std::exception& e) {
    std::printf("FAIL: %s\n", e.what());
    return 1;
  }
}
