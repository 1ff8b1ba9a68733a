// The velocity programs on hand-made constraint sets whose answers are known.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "magna_orca_cpp/linear_program.h"

using magna_orca::Objective;
using magna_orca::Plane;
using magna_orca::Solution;
using magna_orca::solveVelocity;
using magna_orca::Vector3;
using magna_orca::violation;

namespace
{
constexpr double kTol = 1e-9;

Plane plane(const Vector3& point, const Vector3& normal)
{
  return Plane{ point, normal.normalized() };
}

void expectNear(const Vector3& actual, const Vector3& expected, double tol = kTol)
{
  EXPECT_NEAR((actual - expected).norm(), 0.0, tol) << "actual " << actual.transpose() << " expected "
                                                    << expected.transpose();
}

double largestViolation(const std::vector<Plane>& planes, const Vector3& v)
{
  double worst = -INFINITY;
  for (const Plane& p : planes)
    worst = std::max(worst, violation(p, v));
  return worst;
}
}  // namespace

TEST(MaxSpeedSphere, PreferredInsideIsKept)
{
  const Solution s = solveVelocity({}, 2.0, Vector3(0.3, -1.0, 0.5));
  EXPECT_TRUE(s.feasible);
  expectNear(s.velocity, Vector3(0.3, -1.0, 0.5));
}

TEST(MaxSpeedSphere, PreferredOutsideIsScaledOntoTheSphere)
{
  const Solution s = solveVelocity({}, 2.0, Vector3(3.0, 4.0, 0.0));
  EXPECT_TRUE(s.feasible);
  expectNear(s.velocity, Vector3(1.2, 1.6, 0.0));
}

TEST(MaxSpeedSphere, PlaneCuttingTheSphereGivesTheDiscPointNearestTheTarget)
{
  // v.z >= 1 within |v| <= 2: the target far along x lands on the disc's rim at z = 1.
  const std::vector<Plane> planes{ plane(Vector3(0, 0, 1), Vector3::UnitZ()) };
  const Solution s = solveVelocity(planes, 2.0, Vector3(10.0, 0.0, 0.0));
  EXPECT_TRUE(s.feasible);
  expectNear(s.velocity, Vector3(std::sqrt(3.0), 0.0, 1.0));
}

TEST(MaxSpeedSphere, PlaneBeyondTheSphereIsInfeasibleAndTheSphereTouchesIt)
{
  // v.x >= 3 cannot be met at speed 2: the least violation is the sphere's point along +x.
  const std::vector<Plane> planes{ plane(Vector3(3, 0, 0), Vector3::UnitX()) };
  const Solution s = solveVelocity(planes, 2.0, Vector3(0.0, 1.0, 0.0));
  EXPECT_FALSE(s.feasible);
  expectNear(s.velocity, Vector3(2.0, 0.0, 0.0));
  EXPECT_NEAR(violation(planes[0], s.velocity), 1.0, kTol);
}

TEST(SinglePlane, ViolatedTargetIsProjectedOntoThePlane)
{
  const std::vector<Plane> planes{ plane(Vector3(0, 0.5, 0), Vector3(0, 1, 1)) };
  const Vector3 target(0.2, -0.4, -0.3);
  const Solution s = solveVelocity(planes, 5.0, target);
  EXPECT_TRUE(s.feasible);
  const Vector3 n = Vector3(0, 1, 1).normalized();
  expectNear(s.velocity, target + n.dot(Vector3(0, 0.5, 0) - target) * n);
}

TEST(SinglePlane, SatisfiedTargetIsKept)
{
  const std::vector<Plane> planes{ plane(Vector3(0, 0, -1), Vector3::UnitZ()) };
  const Solution s = solveVelocity(planes, 5.0, Vector3(1, 1, 0));
  EXPECT_TRUE(s.feasible);
  expectNear(s.velocity, Vector3(1, 1, 0));
}

TEST(ParallelPlanes, SameDirectionTheStricterOneBinds)
{
  const std::vector<Plane> planes{ plane(Vector3(0, 0, 0.5), Vector3::UnitZ()),
                                   plane(Vector3(0, 0, 1.0), Vector3::UnitZ()),
                                   plane(Vector3(0, 0, 0.2), Vector3::UnitZ()) };
  const Solution s = solveVelocity(planes, 3.0, Vector3(1, 0, 0));
  EXPECT_TRUE(s.feasible);
  expectNear(s.velocity, Vector3(1, 0, 1));
}

TEST(ParallelPlanes, OpposedWithRoomBetweenKeepsTheTargetInTheSlab)
{
  const std::vector<Plane> planes{ plane(Vector3(0, 0, 0.5), Vector3::UnitZ()),
                                   plane(Vector3(0, 0, 1.5), -Vector3::UnitZ()) };
  const Solution s = solveVelocity(planes, 3.0, Vector3(0.5, 0, 4.0));
  EXPECT_TRUE(s.feasible);
  expectNear(s.velocity, Vector3(0.5, 0, 1.5));
}

TEST(ParallelPlanes, OpposedWithoutRoomSplitsTheViolationEvenly)
{
  // z >= 1 and z <= -1: nothing qualifies; the best is z = 0, one unit outside each.
  const std::vector<Plane> planes{ plane(Vector3(0, 0, 1), Vector3::UnitZ()),
                                   plane(Vector3(0, 0, -1), -Vector3::UnitZ()) };
  const Solution s = solveVelocity(planes, 3.0, Vector3(0.5, 0.5, 2.0));
  EXPECT_FALSE(s.feasible);
  EXPECT_NEAR(s.velocity.z(), 0.0, kTol);
  EXPECT_NEAR(largestViolation(planes, s.velocity), 1.0, kTol);
  EXPECT_LE(s.velocity.norm(), 3.0 + kTol);
}

TEST(Corners, ThreeOrthogonalPlanesMeetAtTheCorner)
{
  const std::vector<Plane> planes{ plane(Vector3(1, 0, 0), Vector3::UnitX()), plane(Vector3(0, 1, 0), Vector3::UnitY()),
                                   plane(Vector3(0, 0, 1), Vector3::UnitZ()) };
  const Solution s = solveVelocity(planes, 5.0, Vector3(-1, -1, -1));
  EXPECT_TRUE(s.feasible);
  expectNear(s.velocity, Vector3(1, 1, 1));
}

TEST(Corners, TwoPlanesMeetOnALineAndTheTargetIsProjectedOntoIt)
{
  const std::vector<Plane> planes{ plane(Vector3(1, 0, 0), Vector3::UnitX()), plane(Vector3(0, 1, 0), Vector3::UnitY()) };
  const Solution s = solveVelocity(planes, 5.0, Vector3(0, 0, 2));
  EXPECT_TRUE(s.feasible);
  expectNear(s.velocity, Vector3(1, 1, 2));
}

TEST(Infeasible, SymmetricTrapEqualisesTheViolations)
{
  // Four planes each demanding 2 m/s outwards along +-x and +-y: the best is to stay still,
  // 2 outside each; any move raises the largest violation.
  const std::vector<Plane> planes{ plane(Vector3(2, 0, 0), Vector3::UnitX()), plane(Vector3(-2, 0, 0), -Vector3::UnitX()),
                                   plane(Vector3(0, 2, 0), Vector3::UnitY()), plane(Vector3(0, -2, 0), -Vector3::UnitY()) };
  const Solution s = solveVelocity(planes, 1.0, Vector3(1, 1, 0));
  EXPECT_FALSE(s.feasible);
  EXPECT_NEAR(largestViolation(planes, s.velocity), 2.0, kTol);
  EXPECT_NEAR(s.velocity.x(), 0.0, kTol);
  EXPECT_NEAR(s.velocity.y(), 0.0, kTol);
}

TEST(Infeasible, LeastViolationBeatsEveryOtherCandidate)
{
  // An infeasible tetrahedron-like set: compare the answer against a dense sample of the sphere.
  const std::vector<Plane> planes{ plane(Vector3(1.5, 0, 0), Vector3(1, 0.2, 0)),
                                   plane(Vector3(-0.5, 0, 0), Vector3(-1, 0.1, 0.3)),
                                   plane(Vector3(0, 1.2, 0), Vector3(0.1, 1, -0.2)),
                                   plane(Vector3(0, 0, -1.1), Vector3(0, -0.3, -1)) };
  const Solution s = solveVelocity(planes, 1.0, Vector3(0.2, 0.1, 0.0));
  EXPECT_FALSE(s.feasible);
  const double ours = largestViolation(planes, s.velocity);
  EXPECT_LE(s.velocity.norm(), 1.0 + kTol);
  for (int i = -20; i <= 20; ++i)
    for (int j = -20; j <= 20; ++j)
      for (int k = -20; k <= 20; ++k)
      {
        const Vector3 v(i / 20.0, j / 20.0, k / 20.0);
        if (v.norm() <= 1.0)
          EXPECT_LE(ours, largestViolation(planes, v) + kTol) << "better candidate " << v.transpose();
      }
}

TEST(LineProgram, LineMissingTheSphereHasNoSolution)
{
  Vector3 result;
  const Objective nearest{ Vector3::Zero(), false };
  EXPECT_FALSE(magna_orca::solveOnLine(nullptr, 0, Vector3(0, 0, 3), Vector3::UnitX(), 2.0, nearest, result));
  ASSERT_TRUE(magna_orca::solveOnLine(nullptr, 0, Vector3(0, 0, 1), Vector3::UnitX(), 2.0, nearest, result));
  expectNear(result, Vector3(0, 0, 1));
}

TEST(LineProgram, LineParallelToAPlaneOnItsWrongSideHasNoSolution)
{
  const std::vector<Plane> planes{ plane(Vector3(0, 0, 0.5), Vector3::UnitZ()) };
  Vector3 result;
  const Objective nearest{ Vector3::Zero(), false };
  EXPECT_FALSE(magna_orca::solveOnLine(planes.data(), 1, Vector3::Zero(), Vector3::UnitX(), 2.0, nearest, result));
  EXPECT_TRUE(magna_orca::solveOnLine(planes.data(), 1, Vector3(0, 0, 1), Vector3::UnitX(), 2.0, nearest, result));
}

TEST(LineProgram, DirectionObjectiveTakesTheFarEnd)
{
  const std::vector<Plane> planes{ plane(Vector3(0.5, 0, 0), -Vector3::UnitX()) };  // x <= 0.5
  Vector3 result;
  ASSERT_TRUE(magna_orca::solveOnLine(planes.data(), 1, Vector3::Zero(), Vector3::UnitX(), 2.0,
                                      Objective{ Vector3::UnitX(), true }, result));
  expectNear(result, Vector3(0.5, 0, 0));
  ASSERT_TRUE(magna_orca::solveOnLine(planes.data(), 1, Vector3::Zero(), Vector3::UnitX(), 2.0,
                                      Objective{ -Vector3::UnitX(), true }, result));
  expectNear(result, Vector3(-2.0, 0, 0));
}

TEST(PlaneProgram, PlaneOutsideTheSphereHasNoSolution)
{
  const std::vector<Plane> planes{ plane(Vector3(0, 0, 2.5), Vector3::UnitZ()) };
  Vector3 result;
  EXPECT_FALSE(magna_orca::solveOnPlane(planes.data(), 0, 2.0, Objective{ Vector3::Zero(), false }, result));
}

TEST(PlaneProgram, ParallelEarlierPlaneThatExcludesThisOneHasNoSolution)
{
  // Earlier: z <= 0.5. This one's boundary z = 1 lies wholly outside it.
  const std::vector<Plane> planes{ plane(Vector3(0, 0, 0.5), -Vector3::UnitZ()), plane(Vector3(0, 0, 1), Vector3::UnitZ()) };
  Vector3 result;
  EXPECT_FALSE(magna_orca::solveOnPlane(planes.data(), 1, 2.0, Objective{ Vector3::Zero(), false }, result));
}
