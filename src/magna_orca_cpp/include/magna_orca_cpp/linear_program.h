// The velocity programs of ORCA-3D: the velocity nearest the preferred one inside the
// max-speed sphere and every half-space, by Seidel-style incremental linear programming
// (one dimension lower each time a constraint is violated), and, when the half-spaces
// leave nothing, the velocity that minimises the largest violation.
#pragma once

#include <cstddef>
#include <vector>

#include "magna_orca_cpp/types.h"

namespace magna_orca
{
// What a program optimises: the point nearest `target`, or the point furthest along the
// unit vector `target`.
struct Objective
{
  Vector3 target;
  bool is_direction;
};

// On the line origin + t * direction (direction of unit length), within the sphere of
// `radius` and the first `count` planes. Returns false when nothing on the line qualifies.
bool solveOnLine(const Plane* planes, std::size_t count, const Vector3& origin, const Vector3& direction,
                 double radius, const Objective& objective, Vector3& result);

// On the boundary of planes[index], within the sphere and planes[0 .. index).
bool solveOnPlane(const Plane* planes, std::size_t index, double radius, const Objective& objective,
                  Vector3& result);

// In the sphere and all `count` planes. Returns `count` on success, otherwise the index of
// the first plane that could not be met (result then holds the optimum of the planes before it).
std::size_t solveInSpace(const Plane* planes, std::size_t count, double radius, const Objective& objective,
                         Vector3& result);

// Starting from the optimum of planes[0 .. first_failed), the velocity in the sphere whose
// largest violation of any plane is smallest. `scratch` is reused between calls.
void leastViolation(const Plane* planes, std::size_t count, std::size_t first_failed, double radius,
                    Vector3& result, std::vector<Plane>& scratch);

// The ORCA velocity program: nearest to `preferred` within speed `max_speed` and every plane.
Solution solveVelocity(const std::vector<Plane>& planes, double max_speed, const Vector3& preferred,
                       std::vector<Plane>& scratch);
Solution solveVelocity(const std::vector<Plane>& planes, double max_speed, const Vector3& preferred);

// How far `velocity` is outside `plane` (<= 0 when it satisfies it).
inline double violation(const Plane& plane, const Vector3& velocity)
{
  return plane.normal.dot(plane.point - velocity);
}

}  // namespace magna_orca
