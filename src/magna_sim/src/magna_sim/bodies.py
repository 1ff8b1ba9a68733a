"""pybullet bodies for UAVs and the ground.

A UAV is one rigid body: a cylinder of the airframe's radius and height whose
frame origin is the bottom centre, so a landed UAV reports z = 0 like a real UAL
at its home. Its centre of mass is that origin and its inertia the airframe's.
"""
from __future__ import annotations

import pybullet as p

from magna_common.airframes import Airframe, AirframeError

GROUND_NAME = "ground"


def create_ground(client: int) -> int:
    """An infinite static plane at z = 0."""
    shape = p.createCollisionShape(p.GEOM_PLANE, physicsClientId=client)
    # No visual shape: pybullet has no visual plane and renders the collision plane instead.
    return p.createMultiBody(baseMass=0.0, baseCollisionShapeIndex=shape, physicsClientId=client)


def create_uav_body(client: int, airframe: Airframe, position, orientation_xyzw,
                    rgba=(0.2, 0.2, 0.25, 1.0)) -> int:
    body = airframe.body
    if body is None:
        raise AirframeError(f"{airframe.source}: 'body': missing; a UAV's body takes its size, mass and inertia "
                            "from it")
    half = [0.0, 0.0, body.height / 2.0]
    shape = p.createCollisionShape(p.GEOM_CYLINDER, radius=body.radius, height=body.height,
                                   collisionFramePosition=half, physicsClientId=client)
    visual = p.createVisualShape(p.GEOM_CYLINDER, radius=body.radius, length=body.height,
                                 visualFramePosition=half, rgbaColor=list(rgba), physicsClientId=client)
    body_id = p.createMultiBody(baseMass=body.mass, baseCollisionShapeIndex=shape, baseVisualShapeIndex=visual,
                                basePosition=list(position), baseOrientation=list(orientation_xyzw),
                                physicsClientId=client)
    # pybullet would derive the inertia from the cylinder; the airframe's moments are the real ones.
    p.changeDynamics(body_id, -1, localInertiaDiagonal=list(body.inertia), linearDamping=0.0, angularDamping=0.0,
                     physicsClientId=client)
    return body_id
