#include "tabletop_shapes/core/normals.h"
#include "tabletop_shapes/core/parallel.h"

#include <gtest/gtest.h>
#include <pcl/common/centroid.h>
#include <pcl/search/kdtree.h>
#include <pcl/surface/mls.h>

#include <pcl/common/eigen.h>

#include <Eigen/Cholesky>

#include <chrono>
#include <cstring>
#include <limits>
#include <random>

#include "synthetic.h"

namespace tabletop_shapes {
namespace {

float angleDeg(const Eigen::Vector3f& a, const Eigen::Vector3f& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0f, 1.0f)) * 180.0f /
         static_cast<float>(kPi);
}

// A 0.2 m square plane 1 m in front of the camera, tilted 40 deg, with Gaussian noise, sampled
// at 5 mm (the voxel grid's spacing).
CloudPtr noisyPlane(const Eigen::Vector3f& normal, float sigma, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> noise(0.0f, sigma);
  const Eigen::Vector3f centre(0.1f, 0.05f, 1.0f);
  const Eigen::Vector3f u = normal.unitOrthogonal(), v = normal.cross(u);
  auto cloud = std::make_shared<Cloud>();
  for (float a = -0.1f; a <= 0.1f; a += 0.005f) {
    for (float b = -0.1f; b <= 0.1f; b += 0.005f) {
      const Eigen::Vector3f p =
          centre + a * u + b * v + Eigen::Vector3f(noise(rng), noise(rng), noise(rng));
      cloud->push_back(Point(p.x(), p.y(), p.z()));
    }
  }
  return cloud;
}

TEST(NormalsMLS, NoisyPlaneNormalsWithinFewDegreesAndFacingTheCamera) {
  // Normal facing away from the camera (+z forward): the estimate must be flipped to -normal.
  const Eigen::Vector3f away = Eigen::Vector3f(0.0f, std::sin(0.7f), std::cos(0.7f));
  const CloudPtr plane = noisyPlane(away, 0.0015f, 3);
  NormalCloud out;
  estimateNormalsMLS(plane, NormalParams{}, out);
  ASSERT_GT(out.size(), plane->size() * 95 / 100);  // only a few border points may go
  EXPECT_EQ(out.width, out.size());
  EXPECT_TRUE(out.is_dense);
  float worst = 0.0f, sum = 0.0f;
  int interior = 0;
  for (const auto& p : out.points) {
    const Eigen::Vector3f n = p.getNormalVector3fMap();
    EXPECT_NEAR(n.norm(), 1.0f, 1e-4f);
    EXPECT_GT(n.dot(-p.getVector3fMap()), 0.0f) << "normal not towards the camera";
    const float error = angleDeg(n, -away);
    sum += error;
    // Border points have a one-sided neighbourhood: judge the worst case on the interior.
    if ((p.getVector3fMap() - Eigen::Vector3f(0.1f, 0.05f, 1.0f)).norm() < 0.08f) {
      worst = std::max(worst, error);
      ++interior;
    }
  }
  ASSERT_GT(interior, 500);
  EXPECT_LT(sum / out.size(), 3.0f);
  EXPECT_LT(worst, 8.0f);
}

TEST(NormalsMLS, SmoothsTheNoiseAlongTheNormal) {
  const Eigen::Vector3f normal(0.0f, 0.0f, -1.0f);
  const CloudPtr plane = noisyPlane(normal, 0.002f, 5);
  NormalCloud out;
  estimateNormalsMLS(plane, NormalParams{}, out);
  ASSERT_FALSE(out.empty());
  // Plane z = 1: the raw points deviate by sigma = 2 mm, the MLS projections much less.
  double raw = 0.0, smoothed = 0.0;
  for (const auto& p : plane->points) raw += (p.z - 1.0) * (p.z - 1.0);
  for (const auto& p : out.points) smoothed += (p.z - 1.0) * (p.z - 1.0);
  EXPECT_NEAR(std::sqrt(raw / plane->size()), 0.002, 0.0003);
  EXPECT_LT(std::sqrt(smoothed / out.size()), 0.0008);
}

TEST(NormalsMLS, BoxFacesInCameraFrame) {
  // A 0.175 x 0.12 x 0.10 box 1 m from a camera at the origin, 5 mm spacing, 1.5 mm noise.
  synthetic::Sampler sampler;
  sampler.spacing = 0.005f;
  sampler.noise_sigma = 0.0015f;
  const Eigen::Vector3f size(0.175f, 0.12f, 0.10f);
  CloudPtr box = synthetic::box(size, {0.0f, 0.0f}, 0.0f, sampler);
  // Camera at sampler.camera: moving it to the origin keeps the table frame's axes.
  synthetic::transformCloud(Eigen::Isometry3f(Eigen::Translation3f(-sampler.camera)), *box);
  NormalCloud out;
  const auto start = std::chrono::steady_clock::now();
  estimateNormalsMLS(box, NormalParams{}, out);
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  std::printf("MLS normals: %zu points in %.2f ms\n", box->size(), ms);
  // Printed only: a wall-time bound flaked under load (217 ms against 100); speed is shown by
  // make benchmark-speed and callgrind, not by timed tests.
  ASSERT_GT(out.size(), box->size() * 95 / 100);

  // Away from the edges (> 2.5 cm, beyond the MLS radius) a top-face normal is +z and a
  // front-face normal is -y.
  const Eigen::Vector3f c = -sampler.camera;  // box bottom centre in the shifted frame
  int top = 0, front = 0;
  for (const auto& p : out.points) {
    const Eigen::Vector3f q = p.getVector3fMap() - c;
    const Eigen::Vector3f n = p.getNormalVector3fMap();
    const bool inner_x = std::abs(q.x()) < size.x() / 2 - 0.025f;
    if (inner_x && std::abs(q.y()) < size.y() / 2 - 0.025f && q.z() > size.z() - 0.005f) {
      EXPECT_LT(angleDeg(n, Eigen::Vector3f::UnitZ()), 5.0f);
      ++top;
    }
    if (inner_x && q.y() < -size.y() / 2 + 0.005f && std::abs(q.z() - size.z() / 2) < 0.025f) {
      EXPECT_LT(angleDeg(n, -Eigen::Vector3f::UnitY()), 5.0f);
      ++front;
    }
  }
  EXPECT_GT(top, 50);
  EXPECT_GT(front, 20);
}

TEST(NormalsMLS, SurfaceAndNormalsAreThoseOfPclMovingLeastSquares) {
  // A curved noisy surface, every order the parameter allows: the sums of our fit (grid
  // neighbours, normal equations summed in pairs of doubles) against pcl::MovingLeastSquares
  // (k-d tree, its own matrix products): equal up to the order of floating-point additions.
  auto cloud = std::make_shared<Cloud>();
  std::mt19937 rng(3);
  std::normal_distribution<float> noise(0.0f, 0.001f);
  for (float a = -0.08f; a <= 0.08f; a += 0.005f) {
    for (float b = -0.06f; b <= 0.06f; b += 0.005f) {
      cloud->push_back(Point(a, b + noise(rng), 0.9f + 3.0f * a * a + noise(rng)));
    }
  }
  for (const int order : {1, 2, 3, 4}) {
    NormalParams params;
    params.polynomial_order = order;
    NormalCloud ours;
    estimateNormalsMLS(cloud, params, ours);

    pcl::MovingLeastSquares<Point, pcl::PointNormal> mls;
    mls.setInputCloud(cloud);
    mls.setSearchMethod(std::make_shared<pcl::search::KdTree<Point>>());
    mls.setSearchRadius(params.search_radius);
    mls.setPolynomialOrder(order);
    mls.setComputeNormals(true);
    NormalCloud reference;
    mls.process(reference);

    ASSERT_EQ(ours.size(), reference.size()) << "order " << order;
    for (size_t i = 0; i < ours.size(); ++i) {
      Eigen::Vector3f normal = reference[i].getNormalVector3fMap();
      if (normal.dot(-reference[i].getVector3fMap()) < 0.0f) normal = -normal;  // as ours
      EXPECT_LT((ours[i].getVector3fMap() - reference[i].getVector3fMap()).norm(), 1e-6f)
          << "point " << i << ", order " << order;
      EXPECT_LT((ours[i].getNormalVector3fMap() - normal).norm(), 1e-5f)
          << "point " << i << ", order " << order;
    }
  }
}

// MLS of order 2 as its definition reads, one neighbour and one sum at a time: the neighbours
// within the radius nearest first (ties by index), the plane of their centroid and covariance,
// the weighted normal equations of the height polynomial summed neighbour by neighbour in that
// order, solved by LLT, the query point projected on the polynomial.
pcl::PointNormal definitionOfMls(const Cloud& cloud, size_t query, float radius, bool& fitted) {
  std::vector<std::pair<float, int>> near;
  const Point& q = cloud[query];
  const float radius_squared = static_cast<float>(double(radius) * double(radius));  // as FLANN
  for (size_t j = 0; j < cloud.size(); ++j) {
    const float dx = cloud[j].x - q.x, dy = cloud[j].y - q.y, dz = cloud[j].z - q.z;
    const float d = dx * dx + dy * dy + dz * dz;
    if (d < radius_squared) near.emplace_back(d, static_cast<int>(j));
  }
  std::sort(near.begin(), near.end());
  std::vector<int> neighbours;
  for (const auto& n : near) neighbours.push_back(n.second);
  fitted = neighbours.size() >= 3;
  pcl::MLSResult surface;
  Eigen::Vector4d centroid;
  Eigen::Matrix3d covariance;
  pcl::compute3DCentroid(cloud, neighbours, centroid);
  pcl::computeCovarianceMatrix(cloud, neighbours, centroid, covariance);
  double eigen_value;
  Eigen::Vector3d normal;
  pcl::eigen33(covariance, eigen_value, normal);
  fitted = fitted && normal.allFinite();
  Eigen::Vector4d plane = Eigen::Vector4d::Zero();  // PCL's plane through the centroid
  plane.head<3>() = normal;
  plane[3] = -plane.dot(centroid);
  surface.query_point = q.getVector3fMap().cast<double>();
  const double distance = surface.query_point.dot(normal) + plane[3];
  surface.mean = surface.query_point - distance * normal;
  surface.plane_normal = normal;
  surface.v_axis = normal.unitOrthogonal();
  surface.u_axis = normal.cross(surface.v_axis);
  surface.num_neighbors = static_cast<int>(neighbours.size());
  surface.order = 2;
  if (neighbours.size() >= 6) {
    Eigen::Matrix<double, 6, 6> normal_matrix = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> right = Eigen::Matrix<double, 6, 1>::Zero();
    for (const int n : neighbours) {
      const Eigen::Vector3d offset(cloud[n].x - surface.mean[0], cloud[n].y - surface.mean[1],
                                   cloud[n].z - surface.mean[2]);
      const double weight = std::exp(-offset.dot(offset) / (double(radius) * double(radius)));
      const double u = offset.dot(surface.u_axis), v = offset.dot(surface.v_axis);
      const double terms[6] = {1.0, v, v * v, u, u * v, u * u};  // u^i v^j, j fastest
      for (int a = 0; a < 6; ++a) {
        right[a] += weight * terms[a] * offset.dot(surface.plane_normal);
        for (int b = 0; b <= a; ++b) normal_matrix(a, b) += weight * terms[a] * terms[b];
      }
    }
    surface.c_vec = normal_matrix.selfadjointView<Eigen::Lower>().llt().solve(right);
  }
  const pcl::MLSResult::MLSProjectionResults projected =
      surface.projectQueryPoint(pcl::MLSResult::SIMPLE, 6);
  pcl::PointNormal p;
  p.getVector3fMap() = projected.point.cast<float>();
  Eigen::Vector3f n = projected.normal.cast<float>();
  n /= n.norm();
  if (n.dot(-p.getVector3fMap()) < 0.0f) n = -n;
  p.getNormalVector3fMap() = n;
  return p;
}

bool sameFloats(const Eigen::Vector3f& a, const Eigen::Vector3f& b) {
  return std::memcmp(a.data(), b.data(), sizeof(float) * 3) == 0;
}

// Our fit (neighbours unsorted, sums over pairs of them, normal equations from moments), on one
// thread and shared out over two, gives the definition's surface up to the rounding of the
// sums: a few float ulps at most; and the same floats on one thread as on two.
TEST(NormalsMLS, SurfaceAndNormalOfEveryPointAreThoseOfTheDefinitionUpToRounding) {
  auto cloud = std::make_shared<Cloud>();
  std::mt19937 rng(7);
  std::normal_distribution<float> noise(0.0f, 0.0015f);
  for (float a = -0.06f; a <= 0.06f; a += 0.005f) {
    for (float b = -0.05f; b <= 0.05f; b += 0.005f) {
      cloud->push_back(Point(0.2f + a, b + noise(rng), 1.1f + 2.5f * a * a - b * a + noise(rng)));
    }
  }
  // Four points with 4 neighbours each (a plane, no polynomial); four in a line (no plane, no
  // normal: dropped).
  for (int i = 0; i < 4; ++i) {
    cloud->push_back(Point(0.4f + 0.006f * (i % 2), 0.2f + 0.006f * (i / 2), 1.2f + 0.001f * i));
    cloud->push_back(Point(0.4f + 0.006f * i, 0.3f, 1.2f));
  }
  const NormalParams params;  // order 2, radius 2 cm
  ASSERT_EQ(params.polynomial_order, 2);
  std::vector<pcl::PointNormal> expected;
  for (size_t i = 0; i < cloud->size(); ++i) {
    bool fitted = false;
    const pcl::PointNormal p = definitionOfMls(*cloud, i, params.search_radius, fitted);
    if (fitted) expected.push_back(p);
  }
  EXPECT_EQ(expected.size(), cloud->size() - 4);  // all but the line
  NormalCloud by_thread_count[2];
  for (const unsigned threads : {1u, 2u}) {
    setWorkerThreads(threads);
    NormalCloud& ours = by_thread_count[threads - 1];
    estimateNormalsMLS(cloud, params, ours);
    setWorkerThreads(0);
    ASSERT_EQ(ours.size(), expected.size()) << threads << " threads";
    float worst_point = 0.0f, worst_normal = 0.0f;
    for (size_t i = 0; i < ours.size(); ++i) {
      worst_point =
          std::max(worst_point, (ours[i].getVector3fMap() - expected[i].getVector3fMap()).norm());
      worst_normal =
          std::max(worst_normal,
                   (ours[i].getNormalVector3fMap() - expected[i].getNormalVector3fMap()).norm());
    }
    EXPECT_LT(worst_point, 1e-6f) << threads << " threads";  // ~8 ulps of a float near 1 m
    EXPECT_LT(worst_normal, 1e-5f) << threads << " threads";
  }
  for (size_t i = 0; i < by_thread_count[0].size(); ++i) {
    EXPECT_TRUE(sameFloats(by_thread_count[0][i].getVector3fMap(),
                           by_thread_count[1][i].getVector3fMap()) &&
                sameFloats(by_thread_count[0][i].getNormalVector3fMap(),
                           by_thread_count[1][i].getNormalVector3fMap()))
        << "point " << i;
  }
}

// Order 2 sums its neighbours in floats, in units of the radius: they hold at both ends of the
// radius' range (normals.search_radius 0.002 .. 0.2 m) and of the depth range (0.5 .. 3 m, a
// float's ulp 6e-8 .. 2.4e-7 m): against the definition in doubles, points within 2 ulps of the
// cloud's floats; normals within 1e-5 (as PCL's double fit against its definition) where the
// neighbourhood is whole, and within 1e-3 (0.06 deg) at the patch's border, where a one-sided
// neighbourhood makes the normal equations ill-conditioned (a corner point: 5e-5 .. 1.4e-4).
TEST(NormalsMLS, FloatSumsHoldAcrossTheRadiusRangeAndTheDepthRange) {
  for (const float radius : {0.002f, 0.2f}) {
    for (const float depth : {0.5f, 2.9f}) {
      auto cloud = std::make_shared<Cloud>();
      std::mt19937 rng(11);
      std::normal_distribution<float> noise(0.0f, 0.05f * radius);
      const Eigen::Vector3f centre(0.3f * depth, 0.1f * depth, depth);
      const float spacing = radius / 4.0f, extent = 2.5f * radius;
      for (float a = -extent; a <= extent; a += spacing) {
        for (float b = -extent; b <= extent; b += spacing) {
          // A saddle-like quadric of curvature ~1 / (3 r), tilted towards the camera.
          const float height = (a * a - 0.5f * a * b + 0.3f * b * b) / (3.0f * radius);
          cloud->push_back(Point(centre.x() + a, centre.y() + b + 0.4f * height + noise(rng),
                                 centre.z() + height + noise(rng)));
        }
      }
      NormalParams params;
      params.search_radius = radius;
      NormalCloud ours;
      estimateNormalsMLS(cloud, params, ours);
      std::vector<pcl::PointNormal> expected;
      for (size_t i = 0; i < cloud->size(); ++i) {
        bool fitted = false;
        const pcl::PointNormal p = definitionOfMls(*cloud, i, radius, fitted);
        if (fitted) expected.push_back(p);
      }
      ASSERT_EQ(ours.size(), expected.size()) << "radius " << radius << ", depth " << depth;
      float worst_point = 0.0f, worst_inner_normal = 0.0f, worst_normal = 0.0f;
      int inner = 0;
      for (size_t i = 0; i < ours.size(); ++i) {
        worst_point =
            std::max(worst_point, (ours[i].getVector3fMap() - expected[i].getVector3fMap()).norm());
        const float normal_error =
            (ours[i].getNormalVector3fMap() - expected[i].getNormalVector3fMap()).norm();
        worst_normal = std::max(worst_normal, normal_error);
        const Eigen::Vector3f offset = ours[i].getVector3fMap() - centre;
        if (std::max(std::abs(offset.x()), std::abs(offset.y())) < extent - radius) {
          worst_inner_normal = std::max(worst_inner_normal, normal_error);
          ++inner;
        }
      }
      const float ulp = std::nextafter(depth, 4.0f) - depth;
      EXPECT_GT(inner, 50);
      EXPECT_LT(worst_point, 2.0f * ulp) << "radius " << radius << ", depth " << depth;
      EXPECT_LT(worst_inner_normal, 1e-5f) << "radius " << radius << ", depth " << depth;
      EXPECT_LT(worst_normal, 1e-3f) << "radius " << radius << ", depth " << depth;
      std::printf("radius %.3f m, depth %.1f m: worst point %.3g m, normal %.3g (inner %.3g)\n",
                  radius, depth, worst_point, worst_normal, worst_inner_normal);
    }
  }
}

TEST(NormalsMLS, BadInputGivesAnEmptyDenseCloud) {
  NormalCloud out;
  estimateNormalsMLS(nullptr, NormalParams{}, out);
  EXPECT_TRUE(out.empty());
  estimateNormalsMLS(std::make_shared<Cloud>(), NormalParams{}, out);
  EXPECT_TRUE(out.empty());

  auto nan_cloud = std::make_shared<Cloud>(20, 10);  // organised, all NaN
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (auto& p : nan_cloud->points) p = Point(nan, nan, nan);
  nan_cloud->is_dense = false;
  estimateNormalsMLS(nan_cloud, NormalParams{}, out);
  EXPECT_TRUE(out.empty());
  EXPECT_EQ(out.height, 1u);

  // Two isolated points: no neighbourhood, no normal.
  auto sparse = std::make_shared<Cloud>();
  sparse->push_back(Point(0.0f, 0.0f, 1.0f));
  sparse->push_back(Point(0.5f, 0.0f, 1.0f));
  estimateNormalsMLS(sparse, NormalParams{}, out);
  EXPECT_TRUE(out.empty());

  // Some NaN among valid points: the valid ones get normals.
  CloudPtr mixed = noisyPlane(Eigen::Vector3f(0.0f, 0.0f, -1.0f), 0.0f, 1);
  mixed->push_back(Point(nan, nan, nan));
  mixed->is_dense = false;
  estimateNormalsMLS(mixed, NormalParams{}, out);
  EXPECT_GE(out.size(), mixed->size() * 95 / 100);
  for (const auto& p : out.points) EXPECT_TRUE(std::isfinite(p.x) && std::isfinite(p.normal_z));
}

}  // namespace
}  // namespace tabletop_shapes
