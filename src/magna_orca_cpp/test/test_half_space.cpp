// The ORCA half-space: its geometry on hand-made cases, and the reciprocal guarantee on
// random pairs (both agents inside their half-spaces never collide within the horizon).
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "magna_orca_cpp/half_space.h"
#include "magna_orca_cpp/linear_program.h"

using magna_orca::Agent;
using magna_orca::kFullResponsibility;
using magna_orca::kSharedResponsibility;
using magna_orca::orcaHalfSpace;
using magna_orca::Plane;
using magna_orca::Vector3;
using magna_orca::violation;

namespace
{
Agent agentAt(const Vector3& position, const Vector3& velocity, double radius)
{
  Agent agent;
  agent.position = position;
  agent.velocity = velocity;
  agent.radius = radius;
  agent.max_speed = 10.0;
  return agent;
}

// Smallest centre distance over t in [0, horizon] for a relative position p moving by -v*t
// (v: velocity of the first agent relative to the second).
double closestApproach(const Vector3& p, const Vector3& v, double horizon)
{
  const double speed_sq = v.squaredNorm();
  const double t = speed_sq > 0 ? std::clamp(p.dot(v) / speed_sq, 0.0, horizon) : 0.0;
  return (p - t * v).norm();
}
}  // namespace

TEST(HalfSpace, HeadOnAgentsTurnToOppositeSidesAndShareTheChange)
{
  const Agent a = agentAt(Vector3(0, 0, 0), Vector3(1, 0, 0), 0.5);
  const Agent b = agentAt(Vector3(4, 0, 0), Vector3(-1, 0, 0), 0.5);
  const Plane pa = orcaHalfSpace(a, b, 5.0, 0.1, kSharedResponsibility);
  const Plane pb = orcaHalfSpace(b, a, 5.0, 0.1, kSharedResponsibility);
  EXPECT_NEAR(pa.normal.norm(), 1.0, 1e-12);
  EXPECT_GT(violation(pa, a.velocity), 0.0) << "the current velocity collides, so it must be outside";
  EXPECT_GT(violation(pb, b.velocity), 0.0);
  // Reciprocity: the two planes are mirror images, and each agent moves by half of u.
  EXPECT_NEAR((pa.normal + pb.normal).norm(), 0.0, 1e-12);
  EXPECT_NEAR(violation(pa, a.velocity), violation(pb, b.velocity), 1e-12);
}

TEST(HalfSpace, FullResponsibilityMovesTheWholeWay)
{
  const Agent a = agentAt(Vector3(0, 0, 0), Vector3(1, 0, 0), 0.5);
  Agent obstacle = agentAt(Vector3(4, 0.3, 0), Vector3::Zero(), 1.0);
  obstacle.cooperative = false;
  const Plane half = orcaHalfSpace(a, obstacle, 5.0, 0.1, kSharedResponsibility);
  const Plane full = orcaHalfSpace(a, obstacle, 5.0, 0.1, kFullResponsibility);
  EXPECT_NEAR(violation(full, a.velocity), 2.0 * violation(half, a.velocity), 1e-12);
  // With full responsibility the plane's boundary is the velocity obstacle's boundary:
  // velocities just inside graze the obstacle at the horizon at the latest.
  const Vector3 grazing = full.point + 1e-9 * full.normal;
  EXPECT_GE(closestApproach(obstacle.position - a.position, grazing, 5.0), 1.5 - 1e-6);
  const Vector3 hitting = full.point - 1e-3 * full.normal;
  EXPECT_LT(closestApproach(obstacle.position - a.position, hitting, 5.0), 1.5);
}

TEST(HalfSpace, SlowApproachIsJudgedAgainstTheCutoffCap)
{
  // 0.1 m/s towards something 4 m away: no collision within 2 s, so the plane allows it.
  const Agent a = agentAt(Vector3(0, 0, 0), Vector3(0.1, 0, 0), 0.5);
  const Agent b = agentAt(Vector3(4, 0, 0), Vector3::Zero(), 0.5);
  const Plane p = orcaHalfSpace(a, b, 2.0, 0.1, kFullResponsibility);
  EXPECT_LT(violation(p, a.velocity), 0.0);
  // The boundary is the cap: normal along -x, and it lies at relative speed (4 - 1) / 2.
  EXPECT_NEAR((p.normal - Vector3(-1, 0, 0)).norm(), 0.0, 1e-12);
  EXPECT_NEAR(p.normal.dot(p.point), -1.5, 1e-12);
}

TEST(HalfSpace, OverlappingAgentsAreSeparatedWithinOneTimeStep)
{
  const Agent a = agentAt(Vector3(0, 0, 0), Vector3::Zero(), 0.5);
  const Agent b = agentAt(Vector3(0.5, 0, 0), Vector3::Zero(), 0.5);
  const double step = 0.1;
  const Plane pa = orcaHalfSpace(a, b, 5.0, step, kSharedResponsibility);
  const Plane pb = orcaHalfSpace(b, a, 5.0, step, kSharedResponsibility);
  EXPECT_NEAR((pa.normal - Vector3(-1, 0, 0)).norm(), 0.0, 1e-12);
  // The least each may do: move apart at 2.5 m/s, so after one step they just touch.
  const Vector3 va = pa.point;
  const Vector3 vb = pb.point;
  EXPECT_NEAR(((b.position + step * vb) - (a.position + step * va)).norm(), 1.0, 1e-12);
}

TEST(HalfSpace, CoincidentCentresStillGiveAUnitNormal)
{
  const Agent a = agentAt(Vector3(1, 1, 1), Vector3::Zero(), 0.5);
  const Agent b = agentAt(Vector3(1, 1, 1), Vector3::Zero(), 0.5);
  const Plane p = orcaHalfSpace(a, b, 5.0, 0.1, kSharedResponsibility);
  EXPECT_NEAR(p.normal.norm(), 1.0, 1e-12);
  EXPECT_TRUE(p.point.allFinite());
}

TEST(HalfSpace, VelocityAlongTheAxisHasAWellDefinedEscapeDirection)
{
  for (const Vector3& axis : { Vector3(1, 0, 0), Vector3(0, 1, 0), Vector3(0, 0, 1), Vector3(1, 1, 1).normalized() })
  {
    const Agent a = agentAt(Vector3::Zero(), axis, 0.5);
    const Agent b = agentAt(5.0 * axis, Vector3::Zero(), 0.5);
    const Plane p = orcaHalfSpace(a, b, 10.0, 0.1, kFullResponsibility);
    EXPECT_NEAR(p.normal.norm(), 1.0, 1e-12);
    EXPECT_GT(violation(p, a.velocity), 0.0);
    EXPECT_NEAR(p.normal.dot(axis), -0.2, 1e-12) << "normal leans back from the axis by the cone's angle";
  }
}

// The guarantee of the paper: if both agents pick velocities in their half-spaces, they
// stay at least the combined radius apart for the whole horizon.
TEST(HalfSpace, ReciprocalChoicesNeverCollideWithinTheHorizon)
{
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::uniform_real_distribution<double> radius(0.2, 1.0);
  int checked = 0;
  for (int trial = 0; trial < 20000; ++trial)
  {
    const double tau = 0.5 + 5.0 * (unit(rng) + 1.0);
    const Agent a = agentAt(Vector3::Zero(), 2.0 * Vector3(unit(rng), unit(rng), unit(rng)), radius(rng));
    const Agent b = agentAt(6.0 * Vector3(unit(rng), unit(rng), unit(rng)), 2.0 * Vector3(unit(rng), unit(rng), unit(rng)),
                            radius(rng));
    const double combined = a.radius + b.radius;
    if ((b.position - a.position).norm() <= combined)
      continue;  // the guarantee is about agents that do not overlap yet
    const Plane pa = orcaHalfSpace(a, b, tau, 0.1, kSharedResponsibility);
    const Plane pb = orcaHalfSpace(b, a, tau, 0.1, kSharedResponsibility);
    // Random velocities pushed into each half-space.
    Vector3 va = a.velocity + Vector3(unit(rng), unit(rng), unit(rng));
    Vector3 vb = b.velocity + Vector3(unit(rng), unit(rng), unit(rng));
    va += std::max(0.0, violation(pa, va)) * pa.normal;
    vb += std::max(0.0, violation(pb, vb)) * pb.normal;
    EXPECT_GE(closestApproach(b.position - a.position, va - vb, tau), combined - 1e-9)
        << "trial " << trial;
    ++checked;
  }
  EXPECT_GT(checked, 10000);
}
