// The ORCA half-space one neighbour imposes on an agent's velocity (van den Berg et al., 2011, section 4).
#pragma once

#include "magna_orca_cpp/types.h"

namespace magna_orca
{
// Share of the avoidance an agent takes: half against a cooperative neighbour, all of it
// against one that keeps its course.
constexpr double kSharedResponsibility = 0.5;
constexpr double kFullResponsibility = 1.0;

// Velocities of `self` that stay clear of `other` for `time_horizon` seconds, assuming
// `other` does its share. When the two already overlap, the half-space pushes them apart
// within one `time_step`. Both agents need their radii resolved (> 0).
Plane orcaHalfSpace(const Agent& self, const Agent& other, double time_horizon, double time_step,
                    double responsibility);

// A unit vector perpendicular to the unit vector `axis`, chosen the same way every time.
Vector3 anyPerpendicular(const Vector3& axis);

}  // namespace magna_orca
