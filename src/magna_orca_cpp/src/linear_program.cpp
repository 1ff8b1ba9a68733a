#include "magna_orca_cpp/linear_program.h"

#include <algorithm>
#include <cmath>

namespace magna_orca
{
namespace
{
constexpr double kParallel = 1e-9;  // |cos| or |sin| below this counts as parallel

// The starting point of a program before any plane is considered: the sphere's best point.
Vector3 bestInSphere(double radius, const Objective& objective)
{
  if (objective.is_direction)
    return radius * objective.target;
  const double length_sq = objective.target.squaredNorm();
  if (length_sq > radius * radius)
    return (radius / std::sqrt(length_sq)) * objective.target;
  return objective.target;
}
}  // namespace

bool solveOnLine(const Plane* planes, std::size_t count, const Vector3& origin, const Vector3& direction,
                 double radius, const Objective& objective, Vector3& result)
{
  // The sphere cuts the line in [t_low, t_high]; each plane cuts away one side.
  const double origin_along = origin.dot(direction);
  const double discriminant = origin_along * origin_along + radius * radius - origin.squaredNorm();
  if (discriminant < 0.0)
    return false;
  const double half_chord = std::sqrt(discriminant);
  double t_low = -origin_along - half_chord;
  double t_high = -origin_along + half_chord;

  for (std::size_t j = 0; j < count; ++j)
  {
    const double slope = planes[j].normal.dot(direction);
    const double needed = planes[j].normal.dot(planes[j].point - origin);  // slope * t >= needed
    if (std::abs(slope) <= kParallel)
    {
      if (needed > 0.0)
        return false;  // the whole line lies outside plane j
      continue;
    }
    const double t = needed / slope;
    if (slope > 0.0)
      t_low = std::max(t_low, t);
    else
      t_high = std::min(t_high, t);
    if (t_low > t_high)
      return false;
  }

  double t;
  if (objective.is_direction)
    t = objective.target.dot(direction) > 0.0 ? t_high : t_low;
  else
    t = std::clamp(direction.dot(objective.target - origin), t_low, t_high);
  result = origin + t * direction;
  return true;
}

bool solveOnPlane(const Plane* planes, std::size_t index, double radius, const Objective& objective,
                  Vector3& result)
{
  const Plane& plane = planes[index];
  // The sphere cuts the plane in a disc of centre `centre` and radius disc_radius.
  const double offset = plane.point.dot(plane.normal);
  const double disc_radius_sq = radius * radius - offset * offset;
  if (disc_radius_sq < 0.0)
    return false;
  const double disc_radius = std::sqrt(disc_radius_sq);
  const Vector3 centre = offset * plane.normal;

  if (objective.is_direction)
  {
    const Vector3 along = objective.target - objective.target.dot(plane.normal) * plane.normal;
    const double along_sq = along.squaredNorm();
    result = along_sq > kParallel * kParallel ? Vector3(centre + (disc_radius / std::sqrt(along_sq)) * along) : centre;
  }
  else
  {
    const Vector3 projected = objective.target + (plane.point - objective.target).dot(plane.normal) * plane.normal;
    const Vector3 from_centre = projected - centre;
    const double from_centre_sq = from_centre.squaredNorm();
    result = from_centre_sq > disc_radius_sq ? Vector3(centre + (disc_radius / std::sqrt(from_centre_sq)) * from_centre)
                                             : projected;
  }

  for (std::size_t j = 0; j < index; ++j)
  {
    if (violation(planes[j], result) <= 0.0)
      continue;
    // The optimum now lies on the line where this plane meets plane j.
    const Vector3 crossing = planes[j].normal.cross(plane.normal);
    const double crossing_sq = crossing.squaredNorm();
    if (crossing_sq <= kParallel * kParallel)
      return false;  // parallel: plane j's test has the same value everywhere on this plane, and it fails
    const Vector3 direction = crossing / std::sqrt(crossing_sq);
    const Vector3 across = direction.cross(plane.normal);  // in this plane, perpendicular to the line
    const double step = planes[j].normal.dot(planes[j].point - plane.point) / planes[j].normal.dot(across);
    const Vector3 origin = plane.point + step * across;
    if (!solveOnLine(planes, j, origin, direction, radius, objective, result))
      return false;
  }
  return true;
}

std::size_t solveInSpace(const Plane* planes, std::size_t count, double radius, const Objective& objective,
                         Vector3& result)
{
  result = bestInSphere(radius, objective);
  for (std::size_t i = 0; i < count; ++i)
  {
    if (violation(planes[i], result) <= 0.0)
      continue;
    const Vector3 before = result;
    if (!solveOnPlane(planes, i, radius, objective, result))
    {
      result = before;
      return i;
    }
  }
  return count;
}

void leastViolation(const Plane* planes, std::size_t count, std::size_t first_failed, double radius,
                    Vector3& result, std::vector<Plane>& scratch)
{
  // Incremental in one more dimension (the violation d): when plane i is violated by more
  // than the best d so far, the new optimum has plane i as its most violated plane. There,
  // plane j is no worse than plane i on the side of their bisector, and d falls fastest
  // along plane i's normal.
  double worst = 0.0;
  for (std::size_t i = first_failed; i < count; ++i)
  {
    if (violation(planes[i], result) <= worst)
      continue;
    scratch.clear();
    for (std::size_t j = 0; j < i; ++j)
    {
      const Vector3 normal_gap = planes[j].normal - planes[i].normal;
      const double gap_sq = normal_gap.squaredNorm();
      if (gap_sq <= kParallel * kParallel)
        continue;  // same orientation: plane i stays the more violated of the two everywhere
      // (n_j - n_i) . v >= n_j . q_j - n_i . q_i  <=>  violation_j(v) <= violation_i(v)
      const double offset = planes[j].normal.dot(planes[j].point) - planes[i].normal.dot(planes[i].point);
      scratch.push_back(Plane{ (offset / gap_sq) * normal_gap, normal_gap / std::sqrt(gap_sq) });
    }
    const Vector3 before = result;
    const Objective deepest{ planes[i].normal, true };
    if (solveInSpace(scratch.data(), scratch.size(), radius, deepest, result) < scratch.size())
      result = before;  // only rounding can empty this region; keep the previous optimum
    worst = violation(planes[i], result);
  }
}

Solution solveVelocity(const std::vector<Plane>& planes, double max_speed, const Vector3& preferred,
                       std::vector<Plane>& scratch)
{
  Solution solution;
  const Objective nearest{ preferred, false };
  const std::size_t failed = solveInSpace(planes.data(), planes.size(), max_speed, nearest, solution.velocity);
  if (failed < planes.size())
  {
    leastViolation(planes.data(), planes.size(), failed, max_speed, solution.velocity, scratch);
    solution.feasible = false;
  }
  return solution;
}

Solution solveVelocity(const std::vector<Plane>& planes, double max_speed, const Vector3& preferred)
{
  std::vector<Plane> scratch;
  return solveVelocity(planes, max_speed, preferred, scratch);
}

}  // namespace magna_orca
