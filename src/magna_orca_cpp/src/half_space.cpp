#include "magna_orca_cpp/half_space.h"

#include <algorithm>
#include <cmath>

namespace magna_orca
{
namespace
{
constexpr double kTiny = 1e-12;  // lengths below this have no usable direction
}

Vector3 anyPerpendicular(const Vector3& axis)
{
  // Cross with the coordinate axis least aligned with `axis`, so the result is well conditioned.
  const Vector3 helper = std::abs(axis.x()) < 0.9 ? Vector3::UnitX() : Vector3::UnitY();
  return axis.cross(helper).normalized();
}

Plane orcaHalfSpace(const Agent& self, const Agent& other, double time_horizon, double time_step,
                    double responsibility)
{
  // Work in the frame of `other`: the velocity obstacle is the set of relative velocities
  // that bring the centres closer than the combined radius within the horizon.
  const Vector3 rel_position = other.position - self.position;
  const Vector3 rel_velocity = self.velocity - other.velocity;
  const double dist_sq = rel_position.squaredNorm();
  const double combined_radius = self.radius + other.radius;

  Vector3 normal;  // outward normal of the obstacle's boundary at the point closest to rel_velocity
  Vector3 to_boundary;  // u: smallest change of rel_velocity that reaches that boundary

  if (dist_sq > combined_radius * combined_radius)
  {
    // Truncated cone: apex at the origin, axis rel_position, capped by the sphere of centre
    // rel_position / tau and radius combined_radius / tau.
    const double inv_tau = 1.0 / time_horizon;
    const Vector3 from_cap_centre = rel_velocity - inv_tau * rel_position;
    const double along_axis = from_cap_centre.dot(rel_position);
    const bool nearest_on_cap = along_axis < 0.0 &&
                                along_axis * along_axis > combined_radius * combined_radius * from_cap_centre.squaredNorm();
    if (nearest_on_cap)
    {
      const double length = from_cap_centre.norm();
      normal = from_cap_centre / length;
      to_boundary = (combined_radius * inv_tau - length) * normal;
    }
    else
    {
      // Nearest point on the cone's side, found in the half-plane spanned by the axis and
      // the radial part of rel_velocity: the side is the ray at angle theta from the axis.
      const double dist = std::sqrt(dist_sq);
      const Vector3 axis = rel_position / dist;
      const double sin_theta = combined_radius / dist;
      const double cos_theta = std::sqrt(dist_sq - combined_radius * combined_radius) / dist;
      const double axial = rel_velocity.dot(axis);
      const Vector3 radial_part = rel_velocity - axial * axis;
      const double radial = radial_part.norm();
      const Vector3 radial_dir = radial > kTiny ? Vector3(radial_part / radial) : anyPerpendicular(axis);
      const double along_side = std::max(0.0, axial * cos_theta + radial * sin_theta);
      const Vector3 on_side = along_side * (cos_theta * axis + sin_theta * radial_dir);
      normal = cos_theta * radial_dir - sin_theta * axis;
      to_boundary = on_side - rel_velocity;
    }
  }
  else
  {
    // Already overlapping: leave the overlap within one time step instead of one horizon.
    const double inv_step = 1.0 / time_step;
    const Vector3 from_centre = rel_velocity - inv_step * rel_position;
    double length = from_centre.norm();
    if (length > kTiny)
    {
      normal = from_centre / length;
    }
    else
    {
      const double dist = std::sqrt(dist_sq);
      normal = dist > kTiny ? Vector3(-rel_position / dist) : Vector3(Vector3::UnitX());
      length = 0.0;
    }
    to_boundary = (combined_radius * inv_step - length) * normal;
  }

  return Plane{ self.velocity + responsibility * to_boundary, normal };
}

}  // namespace magna_orca
