// Registration against an analytic scene: a box with two spherical bumps (no rotational
// symmetry) on the turntable, ray-cast into a pinhole grid at known poses. The true poses are
// constructed here, so every check is against geometry the code under test never sees.
#include "processing/registration/registration.h"

#include "core/errors.h"

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <limits>
#include <numbers>
#include <optional>
#include <random>

namespace sherd::registration {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

struct Hit {
  double t;
  Vec3d normal;
};

// Entry point of a ray (origin outside) into an axis-aligned box: slab method.
std::optional<Hit> hit_box(const Vec3d& o, const Vec3d& d, const Vec3d& lo, const Vec3d& hi) {
  double t_in = -std::numeric_limits<double>::infinity();
  double t_out = std::numeric_limits<double>::infinity();
  Vec3d normal = Vec3d::Zero();
  for (int a = 0; a < 3; ++a) {
    if (std::abs(d[a]) < 1e-12) {
      if (o[a] < lo[a] || o[a] > hi[a]) return std::nullopt;
      continue;
    }
    double t0 = (lo[a] - o[a]) / d[a], t1 = (hi[a] - o[a]) / d[a];
    double sign = -1.0;  // entering through the low face: outward normal −axis
    if (t0 > t1) {
      std::swap(t0, t1);
      sign = 1.0;
    }
    if (t0 > t_in) {
      t_in = t0;
      normal = Vec3d::Zero();
      normal[a] = sign;
    }
    t_out = std::min(t_out, t1);
  }
  if (t_in > t_out || t_in <= 0) return std::nullopt;
  return Hit{t_in, normal};
}

std::optional<Hit> hit_sphere(const Vec3d& o, const Vec3d& d, const Vec3d& c, double r) {
  const Vec3d oc = o - c;
  const double b = oc.dot(d), disc = b * b - (oc.squaredNorm() - r * r);
  if (disc < 0) return std::nullopt;
  const double t = -b - std::sqrt(disc);
  if (t <= 0) return std::nullopt;
  return Hit{t, (o + t * d - c).normalized()};
}

// The scene, world (= turntable) frame, mm.
const Vec3d kBoxLo(-40, -25, 0), kBoxHi(40, 25, 60);
const Vec3d kBumpTop(25, 10, 60), kBumpSide(-40, 5, 30);
constexpr double kBumpTopR = 15, kBumpSideR = 12;

// A ray starting outside convex solids first meets their union where it enters any of them.
std::optional<Hit> hit_scene(const Vec3d& o, const Vec3d& d) {
  std::optional<Hit> best;
  for (auto hit : {hit_box(o, d, kBoxLo, kBoxHi), hit_sphere(o, d, kBumpTop, kBumpTopR),
                   hit_sphere(o, d, kBumpSide, kBumpSideR)}) {
    if (hit && (!best || hit->t < best->t)) best = hit;
  }
  return best;
}

// Scanner 350 mm from the axis, 150 mm up, looking at the object's middle (optical axis = +z,
// image x right, y down).
Pose scanner_to_world() {
  const Vec3d eye(350, 0, 150), target(0, 0, 30);
  const Vec3d z = (target - eye).normalized();
  const Vec3d x = z.cross(Vec3d::UnitZ()).normalized();
  const Vec3d y = z.cross(x);
  Pose pose = Pose::Identity();
  pose.linear().col(0) = x;
  pose.linear().col(1) = y;
  pose.linear().col(2) = z;
  pose.translation() = eye;
  return pose;
}

// A solid of revolution about the turntable axis with nothing on it to fix the rotation about
// that axis: a closed cone frustum (radius 70 mm on the plate, 40 mm at its flat top, 60 mm up).
constexpr double kConeBaseR = 70, kConeSlope = -0.5, kConeHeight = 60;

std::optional<Hit> hit_frustum(const Vec3d& o, const Vec3d& d) {
  std::optional<Hit> best;
  // Side: |p_xy|² = (kConeBaseR + kConeSlope·p_z)² along p = o + t·d, a quadratic in t; the
  // nearer root is where the ray enters the (convex) solid.
  const double r0 = kConeBaseR + kConeSlope * o.z();
  const double a = d.x() * d.x() + d.y() * d.y() - kConeSlope * kConeSlope * d.z() * d.z();
  const double b = 2 * (o.x() * d.x() + o.y() * d.y() - kConeSlope * d.z() * r0);
  const double c = o.x() * o.x() + o.y() * o.y() - r0 * r0;
  const double disc = b * b - 4 * a * c;
  if (disc >= 0 && std::abs(a) > 1e-12) {
    const double t = std::min((-b - std::sqrt(disc)) / (2 * a), (-b + std::sqrt(disc)) / (2 * a));
    const Vec3d p = o + t * d;
    if (t > 0 && p.z() >= 0 && p.z() <= kConeHeight) {
      // The gradient of |p_xy|² − (radius at p_z)², pointing out of the solid.
      const Vec3d normal(p.x(), p.y(), -kConeSlope * (kConeBaseR + kConeSlope * p.z()));
      best = Hit{t, normal.normalized()};
    }
  }
  // Top: the disc z = kConeHeight, seen from above.
  if (d.z() < 0) {
    const double t = (kConeHeight - o.z()) / d.z();
    const Vec3d p = o + t * d;
    const double top_r = kConeBaseR + kConeSlope * kConeHeight;
    if (t > 0 && p.head<2>().norm() <= top_r && (!best || t < best->t)) {
      best = Hit{t, Vec3d::UnitZ()};
    }
  }
  return best;
}

using SceneHit = std::optional<Hit> (*)(const Vec3d&, const Vec3d&);

// The surface's colour at a world point.
using SurfaceColour = Rgb8 (*)(const Vec3d&);
Rgb8 plain_clay(const Vec3d&) { return Rgb8{180, 120, 90}; }

// One view seen from `true_pose` (scanner → world), with 0.05 mm depth noise. `lit_by_scanner`:
// the colour is shaded by a light at the scanner (cosine of the incidence, as a projector beside
// the camera lights the clay), so every view darkens towards the pot's silhouette.
OrganisedView capture(const Pose& true_pose, unsigned seed, SceneHit hit_surface = hit_scene,
                      SurfaceColour colour_at = plain_clay, bool lit_by_scanner = false) {
  constexpr int kWidth = 320, kHeight = 240;
  constexpr double kFocal = 600;
  OrganisedView view;
  view.width = kWidth;
  view.height = kHeight;
  view.points.assign(view.cells(), Vec3f::Constant(std::nanf("")));
  view.normals.assign(view.cells(), Vec3f::Zero());
  view.colours.assign(view.cells(), Rgb8{});
  view.valid.assign(view.cells(), 0);
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.05), camera_noise(0.0, 1.5);
  const Pose world_to_scanner = true_pose.inverse();
  for (int v = 0; v < kHeight; ++v) {
    for (int u = 0; u < kWidth; ++u) {
      const Vec3d ray =
          Vec3d((u - kWidth / 2.0) / kFocal, (v - kHeight / 2.0) / kFocal, 1).normalized();
      const auto hit = hit_surface(true_pose.translation(), true_pose.linear() * ray);
      if (!hit) continue;
      const std::size_t c = static_cast<std::size_t>(v) * kWidth + u;
      view.points[c] = ((hit->t + noise(rng)) * ray).cast<float>();
      view.normals[c] = (world_to_scanner.linear() * hit->normal).cast<float>();
      const Vec3d world_ray = true_pose.linear() * ray;
      Rgb8 colour = colour_at(true_pose.translation() + hit->t * world_ray);
      if (lit_by_scanner) {
        const double shade = std::abs(world_ray.dot(hit->normal));
        for (auto* channel : {&colour.r, &colour.g, &colour.b}) {
          *channel = static_cast<std::uint8_t>(
              std::clamp(std::lround(*channel * shade + camera_noise(rng)), 0L, 255L));
        }
      }
      view.colours[c] = colour;
      view.valid[c] = 1;
    }
  }
  return view;
}

// A small rigid error: `deg` about `axis` through the object's middle, then `shift_mm`.
Pose perturbation(double deg, const Vec3d& axis, const Vec3d& shift_mm) {
  const Vec3d centre(0, 0, 30);
  return Eigen::Translation3d(centre + shift_mm) *
         Eigen::AngleAxisd(deg * kDeg, axis.normalized()) * Eigen::Translation3d(-centre);
}

struct PoseError {
  double deg, mm;  // rotation angle; displacement of the object's middle
};

PoseError pose_error(const Pose& estimate, const Pose& truth) {
  const Pose e = estimate * truth.inverse();
  const Vec3d centre(0, 0, 30);
  return {Eigen::AngleAxisd(e.linear()).angle() / kDeg, (e * centre - centre).norm()};
}

bool has_flag(const ViewResult& r, const std::string& flag) {
  return std::find(r.flags.begin(), r.flags.end(), flag) != r.flags.end();
}

class SyntheticTurntable : public ::testing::Test {
 protected:
  static constexpr int kViews = 8;
  static void SetUpTestSuite() {
    for (int i = 0; i < kViews; ++i) {
      truths_.push_back(turntable_prior(scanner_to_world(), i * 2 * std::numbers::pi / kViews));
      views_.push_back(capture(truths_.back(), 100 + i));
    }
  }
  std::vector<ViewInput> inputs_at_truth() const {
    std::vector<ViewInput> in;
    for (int i = 0; i < kViews; ++i) in.push_back({&views_[i], truths_[i]});
    return in;
  }
  static inline std::vector<Pose> truths_;
  static inline std::vector<OrganisedView> views_;
};

TEST(TurntablePrior, RotatesTheScannerPoseBackByTheAngle) {
  // Scanner at x = 100 mm; after the plate turned +90°, its origin sits at −90° in the plate's
  // frame at angle 0: (0, −100, 0).
  const Pose scanner = Pose(Eigen::Translation3d(100, 0, 0));
  const Pose prior = turntable_prior(scanner, std::numbers::pi / 2);
  EXPECT_NEAR((prior * Vec3d::Zero() - Vec3d(0, -100, 0)).norm(), 0.0, 1e-9);
}

// The pose graph's world frame is held by all priors together, so views are compared relative to
// view 0 (a common motion of all views changes nothing in the fused model): view i as placed
// relative to view 0, put where the truth has view 0.
Pose relative_to_view0(const Result& result, const std::vector<Pose>& truths, int i) {
  return truths[0] * result.views[0].pose.inverse() * result.views[i].pose;
}

PoseError relative_error(const Result& result, const std::vector<Pose>& truths, int i) {
  return pose_error(relative_to_view0(result, truths, i), truths[i]);
}

TEST_F(SyntheticTurntable, IdentityPriorsStayPut) {
  const Result result = register_views(inputs_at_truth(), PriorUncertainty{}, Params{});
  ASSERT_EQ(result.views.size(), static_cast<std::size_t>(kViews));
  // Eight neighbours around the loop, plus further overlapping pairs.
  EXPECT_GE(result.edges.size(), static_cast<std::size_t>(kViews));
  for (const auto& e : result.edges) EXPECT_EQ(e.status, "accepted") << e.target << "-" << e.source;
  for (int i = 0; i < kViews; ++i) {
    const auto& r = result.views[i];
    SCOPED_TRACE(::testing::Message() << "view " << i << ", iterations " << r.iterations << ", rms "
                                      << r.rms_mm << ", overlap " << r.overlap);
    EXPECT_TRUE(r.flags.empty()) << r.flags.front();
    EXPECT_TRUE(r.merged);
    const PoseError e = pose_error(r.pose, truths_[i]);
    // Edge voxels leave a bias of a few hundredths of a degree.
    EXPECT_LT(e.deg, 0.05);
    EXPECT_LT(e.mm, 0.1);
    EXPECT_GT(r.overlap, 0.3);
    EXPECT_LT(r.rms_mm, 0.2);  // noise is 0.05 mm
    EXPECT_GE(r.edges, 2);     // both turntable neighbours
  }
}

TEST_F(SyntheticTurntable, RecoversPerturbedPriors) {
  std::vector<ViewInput> in = inputs_at_truth();
  for (int i = 1; i < kViews; ++i) {
    const double deg = 0.5 + 0.5 * (i % 2);  // 0.5° or 1°
    const Vec3d axis(std::sin(i), std::cos(2.0 * i), 1.0);
    const Vec3d shift = Vec3d(std::cos(i), std::sin(i), 0.5).normalized() * (1.0 + (i % 3) * 0.5);
    in[i].prior = perturbation(deg, axis, shift) * truths_[i];
    ASSERT_GT(pose_error(in[i].prior, truths_[i]).deg, 0.4);  // only meaningful if the prior is off
  }
  // What the test's priors are good to: up to 1° about any axis, 2 mm.
  const PriorUncertainty uncertainty{
      .angle_sd_deg = 1.0, .tilt_sd_deg = 1.0, .translation_sd_mm = 2.0};
  const Result result = register_views(in, uncertainty, Params{});
  for (int i = 1; i < kViews; ++i) {
    const auto& r = result.views[i];
    SCOPED_TRACE(::testing::Message() << "view " << i << ", iterations " << r.iterations << ", rms "
                                      << r.rms_mm << ", overlap " << r.overlap);
    EXPECT_TRUE(r.merged);
    const PoseError e = relative_error(result, truths_, i);
    EXPECT_LT(e.deg, 0.05);
    EXPECT_LT(e.mm, 0.1);
    EXPECT_GT(r.iterations, 0);
    EXPECT_GT(r.correction_deg, 0.2);  // it did move from its prior
  }
}

TEST_F(SyntheticTurntable, PriorErrorsSpreadNotAccumulated) {
  // Every prior turned a little further about the turntable axis than the one before (an encoder
  // that counts 0.1 % slow): chaining pairs would carry the drift, the graph spreads it.
  std::vector<ViewInput> in = inputs_at_truth();
  for (int i = 0; i < kViews; ++i)
    in[i].prior = perturbation(0.15 * i, Vec3d::UnitZ(), Vec3d::Zero()) * truths_[i];
  const Result result = register_views(in, PriorUncertainty{.angle_sd_deg = 1.0}, Params{});
  double worst = 0.0;
  for (int i = 1; i < kViews; ++i) worst = std::max(worst, relative_error(result, truths_, i).deg);
  EXPECT_LT(worst, 0.05);  // the box is asymmetric: the geometry sees the angle
}

TEST_F(SyntheticTurntable, AViewWhosePriorMissedStepsIsPlacedByTheGeometry) {
  // View 3's plate stood 3° further than the encoder said (missed steps); the priors say 0.1°.
  std::vector<ViewInput> in = inputs_at_truth();
  in[3].prior = perturbation(3.0, Vec3d::UnitZ(), Vec3d::Zero()) * truths_[3];
  Params params;
  params.max_correction_deg = 5.0;
  const Result result = register_views(in, PriorUncertainty{}, params);
  for (int i = 0; i < kViews; ++i) {
    SCOPED_TRACE(::testing::Message() << "view " << i);
    EXPECT_TRUE(result.views[i].merged);
    // The robust prior lets the geometry win for view 3 without dragging the others.
    EXPECT_LT(pose_error(result.views[i].pose, truths_[i]).deg, 0.05);
  }
  EXPECT_NEAR(result.views[3].correction_deg, 3.0, 0.05);
}

TEST_F(SyntheticTurntable, EmptyViewIsFlaggedAndKeptAtPrior) {
  OrganisedView empty;
  empty.width = 320;
  empty.height = 240;
  empty.points.assign(empty.cells(), Vec3f::Constant(std::nanf("")));
  empty.valid.assign(empty.cells(), 0);
  std::vector<ViewInput> in = inputs_at_truth();
  const Pose prior = perturbation(1.0, Vec3d::UnitX(), Vec3d(2, 0, 0)) * truths_[1];
  in[1] = {&empty, prior};
  const Result result = register_views(in, PriorUncertainty{}, Params{});
  EXPECT_TRUE(has_flag(result.views[1], "empty"));
  EXPECT_FALSE(result.views[1].merged);
  EXPECT_TRUE(result.views[1].pose.isApprox(prior, 0.0));
  // Its neighbours close the gap between them and still land on the truth.
  EXPECT_TRUE(result.views[2].merged);
  EXPECT_LT(pose_error(result.views[2].pose, truths_[2]).deg, 0.05);
}

TEST_F(SyntheticTurntable, ViewWithoutOverlapIsFlaggedAndLeftOut) {
  std::vector<ViewInput> in = inputs_at_truth();
  // 300 mm off: nothing of the other views is anywhere near.
  in[1].prior = Pose(Eigen::Translation3d(300, 0, 0)) * truths_[1];
  const Result result = register_views(in, PriorUncertainty{}, Params{});
  EXPECT_TRUE(has_flag(result.views[1], "no_overlap"));
  EXPECT_FALSE(result.views[1].merged);
  EXPECT_TRUE(result.views[1].pose.isApprox(in[1].prior, 0.0));
  EXPECT_EQ(result.views[1].overlap, 0.0);
  EXPECT_TRUE(result.views[2].merged);
}

TEST_F(SyntheticTurntable, CorrectionBeyondTheLimitIsFlaggedAndLeftOut) {
  std::vector<ViewInput> in = inputs_at_truth();
  // 2° about the turntable axis: the slide a near-symmetric pot allows.
  in[3].prior = perturbation(2.0, Vec3d::UnitZ(), Vec3d::Zero()) * truths_[3];
  Params params;
  params.max_correction_deg = 1.0;
  const Result result = register_views(in, PriorUncertainty{}, params);
  const auto& r = result.views[3];
  EXPECT_TRUE(has_flag(r, "implausible_correction"));
  EXPECT_FALSE(r.merged);
  EXPECT_TRUE(r.pose.isApprox(in[3].prior, 0.0));
  int rejected = 0;
  for (const auto& e : result.edges) {
    if (e.target != 3 && e.source != 3) continue;
    EXPECT_EQ(e.status, "implausible_correction");
    // What ICP found undoes the 2° we put in.
    EXPECT_NEAR(e.correction_deg, 2.0, 0.05);
    ++rejected;
  }
  EXPECT_GE(rejected, 2);
  // The others are not dragged along.
  for (int i : {0, 2, 4}) EXPECT_LT(pose_error(result.views[i].pose, truths_[i]).deg, 0.05);
}

TEST_F(SyntheticTurntable, CorruptInputIsRejected) {
  std::vector<ViewInput> in = inputs_at_truth();
  in.resize(2);
  OrganisedView corrupt = views_[1];
  const auto cell =
      std::find(corrupt.valid.begin(), corrupt.valid.end(), 1) - corrupt.valid.begin();
  corrupt.points[cell] = Vec3f::Constant(std::nanf(""));
  in[1].view = &corrupt;
  EXPECT_THROW(register_views(in, PriorUncertainty{}, Params{}), InputError);

  OrganisedView short_grid = views_[1];
  short_grid.valid.pop_back();
  in[1].view = &short_grid;
  EXPECT_THROW(register_views(in, PriorUncertainty{}, Params{}), InputError);

  in[1] = {nullptr, truths_[1]};
  EXPECT_THROW(register_views(in, PriorUncertainty{}, Params{}), InputError);

  in = inputs_at_truth();
  EXPECT_THROW(register_views(in, PriorUncertainty{.angle_sd_deg = 0.0}, Params{}), InputError);
  EXPECT_THROW(register_views(in, PriorUncertainty{.translation_sd_mm = std::nan("")}, Params{}),
               InputError);
}

// The signed rotation of `rotation` about the world z axis (swing-twist), degrees.
double twist_about_z_deg(const Eigen::Matrix3d& rotation) {
  const Eigen::Quaterniond q(rotation);
  return 2.0 * std::atan2(q.z(), q.w()) / kDeg;
}

// The turntable and frustum share their axis (world z), so it looks the same at any rotation
// about it: geometry cannot tell a prior's error about z, only the turntable can.
class SymmetricPot : public ::testing::Test {
 protected:
  static constexpr int kViews = 6;
  static constexpr double kPriorTwistDeg = 0.5;
  // The priors below are off by 0.5° about the axis and 0.36 mm; the registration is told so.
  static constexpr PriorUncertainty kUncertainty{
      .angle_sd_deg = 0.5, .tilt_sd_deg = 0.05, .translation_sd_mm = 0.4};
  static void SetUpTestSuite() {
    for (int i = 0; i < kViews; ++i) {
      truths_.push_back(turntable_prior(scanner_to_world(), i * 2 * std::numbers::pi / kViews));
      views_.push_back(capture(truths_.back(), 200 + i, hit_frustum));
    }
  }
  // Every view but the reference: 0.5° about the pot's own axis plus a few tenths of a mm.
  static std::vector<ViewInput> perturbed_inputs(const std::vector<OrganisedView>& views = views_) {
    std::vector<ViewInput> in;
    for (int i = 0; i < kViews; ++i) {
      const Vec3d shift = i == 0 ? Vec3d::Zero() : Vec3d(0.3 * std::cos(i), 0.3 * std::sin(i), 0.2);
      const double deg = i == 0 ? 0.0 : kPriorTwistDeg;
      in.push_back({&views[i], perturbation(deg, Vec3d::UnitZ(), shift) * truths_[i]});
    }
    return in;
  }
  struct Split {
    double twist_deg;  // error about the axis: what geometry cannot see
    PoseError rest;    // everything else: what geometry must correct
  };
  static Split split_error(const Pose& estimate, const Pose& truth) {
    const Pose error = estimate * truth.inverse();
    const double twist = twist_about_z_deg(error.linear());
    const Pose rest = Pose(Eigen::AngleAxisd(-twist * kDeg, Vec3d::UnitZ())) * error;
    const Vec3d centre(0, 0, 30);
    return {twist,
            {Eigen::AngleAxisd(rest.linear()).angle() / kDeg, (rest * centre - centre).norm()}};
  }
  // The pot's views captured again in `colour` (lit by the scanner or evenly) and registered with
  // the colour term as the station is configured: at 1 mm voxels the texture blurs (measured:
  // 0.1–0.6° off), at 0.5 mm it is seen.
  static Result register_coloured(SurfaceColour colour, bool lit_by_scanner) {
    std::vector<OrganisedView> views;
    for (int i = 0; i < kViews; ++i) {
      views.push_back(capture(truths_[i], 200 + i, hit_frustum, colour, lit_by_scanner));
    }
    Params with_colour;
    with_colour.use_colour = true;
    with_colour.voxel_mm = 0.5;
    return register_views(perturbed_inputs(views), kUncertainty, with_colour);
  }

  // Every view but the reference within `twist_bound_deg` about the axis (the priors were 0.5° off
  // there) and corrected in every other direction.
  static void expect_texture_fixed_the_twist(const Result& result, double twist_bound_deg) {
    for (int i = 1; i < kViews; ++i) {
      SCOPED_TRACE(::testing::Message() << "view " << i);
      const auto e = split_error(relative_to_view0(result, truths_, i), truths_[i]);
      EXPECT_LT(std::abs(e.twist_deg), twist_bound_deg);
      EXPECT_LT(e.rest.deg, 0.03);
      EXPECT_LT(e.rest.mm, 0.05);
    }
  }
  static inline std::vector<Pose> truths_;
  static inline std::vector<OrganisedView> views_;
};

TEST_F(SymmetricPot, KeepsThePriorAboutTheAxisAndCorrectsTheRest) {
  const Result result = register_views(perturbed_inputs(), kUncertainty, Params{});
  for (int i = 1; i < kViews; ++i) {
    const auto& r = result.views[i];
    SCOPED_TRACE(::testing::Message()
                 << "view " << i << ", iterations " << r.iterations << ", rms " << r.rms_mm);
    EXPECT_TRUE(r.merged);
    // The frustum's only symmetry is the rotation about its axis: one degenerate direction.
    ASSERT_EQ(r.degenerate.size(), 1u);
    EXPECT_EQ(r.degenerate[0].name, "rot_z");
    EXPECT_TRUE(has_flag(r, "degenerate:rot_z"));
    const Split e = split_error(relative_to_view0(result, truths_, i), truths_[i]);
    EXPECT_NEAR(e.twist_deg, kPriorTwistDeg, 0.01);  // kept, not slid
    EXPECT_LT(e.rest.deg, 0.03);
    EXPECT_LT(e.rest.mm, 0.05);  // the prior was 0.36 mm off
  }
}

// Fired clay of colour `base`, mottled by ±`amplitude` over millimetres, fixed to the pot (the
// world frame is the plate's).
Rgb8 mottled(const Vec3d& p, double amplitude, const Vec3d& base) {
  const double k = 1.0 + amplitude * std::sin(2 * std::numbers::pi * p.x() / 7.0) *
                             std::sin(2 * std::numbers::pi * p.y() / 5.0) *
                             std::cos(2 * std::numbers::pi * p.z() / 6.0);
  return Rgb8{static_cast<std::uint8_t>(base.x() * k), static_cast<std::uint8_t>(base.y() * k),
              static_cast<std::uint8_t>(base.z() * k)};
}
Rgb8 mottled_clay(const Vec3d& p) { return mottled(p, 0.25, Vec3d(160, 110, 80)); }
Rgb8 dark_mottled_clay(const Vec3d& p) { return mottled(p, 0.1, Vec3d(70, 50, 40)); }

TEST_F(SymmetricPot, ItsClayTextureFixesWhatItsShapeCannot) {
  const Result result = register_coloured(mottled_clay, false);
  for (const auto& edge : result.edges) EXPECT_EQ(edge.used_colour, edge.neighbours);
  expect_texture_fixed_the_twist(result, 0.05);
}

// A dark, faintly mottled pot under the scanner's own light, with the camera's noise: the shading
// moves with the scanner, not with the clay, and near the silhouette, where the light grazes, it
// changes fastest and the clay is darkest and noisiest. With those rows weighted as evenly as the
// bright ones, one view ended 0.148° off about the axis (the others within 0.05°); weighted by
// their brightness, the worst is 0.088°. The bound is the benchmark's (95th percentile ≤ 0.1°).
TEST_F(SymmetricPot, ADarkPotsTextureFixesItUnderTheScannersOwnLight) {
  expect_texture_fixed_the_twist(register_coloured(dark_mottled_clay, true), 0.1);
}

TEST_F(SymmetricPot, WithoutTheHandlingIcpSlidesAboutTheAxis) {
  // Three views are enough to see it (plain ICP runs to its iteration limit: slow).
  std::vector<ViewInput> in = perturbed_inputs();
  in.resize(3);
  Params plain;
  plain.keep_prior_in_degenerate_directions = false;
  const Result slid = register_views(in, kUncertainty, plain);
  const Result kept = register_views(in, kUncertainty, Params{});
  double worst_slid = 0.0, worst_kept = 0.0;
  const auto twist_error = [&](const Result& r, std::size_t i) {
    return std::abs(
        split_error(relative_to_view0(r, truths_, static_cast<int>(i)), truths_[i]).twist_deg -
        kPriorTwistDeg);
  };
  for (std::size_t i = 1; i < in.size(); ++i) {
    worst_slid = std::max(worst_slid, twist_error(slid, i));
    worst_kept = std::max(worst_kept, twist_error(kept, i));
  }
  std::cout << "slide about the axis from the prior, worst view: plain " << worst_slid
            << " deg, kept " << worst_kept << " deg\n";
  EXPECT_GT(worst_slid, 0.05);
  EXPECT_GT(worst_slid, 5 * worst_kept);
}

}  // namespace
}  // namespace sherd::registration
