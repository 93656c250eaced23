"""The A1's part of every task's world, built in code with `mujoco.MjSpec`: a task starts from
`robot_spec` and adds its ground (a platform, a heightfield), then calls `add_robot_sensors`.

The robot's own MJCF (`lasmp.robots.a1`) is the base spec: the task's bodies are added to its world
(no attach, so names stay as the robot file has them). The sensors are those `lasmp.envs.robot`
reads: `<leg>_foot_contact` (found + net force, world frame) and `<body>_collision` (found) for every
body of `a1.NON_FOOT_COLLISION_GEOMS`. The robot's collision geoms (contype 1) touch a ground of
contype 0, conaffinity 1; the feet keep contact priority so that their randomized friction decides
their contacts.
"""

from __future__ import annotations

import mujoco

from lasmp.config.base import SimCfg
from lasmp.robots import a1


def robot_spec(sim: SimCfg, modelname: str) -> mujoco.MjSpec:
    """The A1's MJCF as a spec named `modelname`, with the simulation options of `sim` and a light."""
    spec = mujoco.MjSpec.from_file(str(a1.MJCF_PATH))
    spec.modelname = modelname
    spec.option.timestep = sim.dt_s
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST  # stiff PDs: implicit damping
    spec.option.iterations = sim.solver_iterations
    spec.option.tolerance = sim.solver_tolerance
    spec.option.ls_iterations = max(5, sim.solver_iterations // 2)
    spec.option.cone = getattr(mujoco.mjtCone, f"mjCONE_{sim.cone.upper()}")
    spec.option.impratio = sim.impratio
    spec.option.noslip_iterations = sim.noslip_iterations
    spec.worldbody.add_light(pos=[0, 0, 12], dir=[0, 0, -1], diffuse=[0.8, 0.8, 0.8])
    return spec


def add_robot_sensors(spec: mujoco.MjSpec) -> None:
    """Give the feet contact priority and add the robot's contact sensors (after the task's own
    sensors: sensordata keeps that order). Contact sensors need the acceleration stage: read after a
    step, they describe its last substep."""
    for leg in a1.LEG_NAMES:
        spec.geom(f"{leg}_foot").priority = 1
    found = 1 << int(mujoco.mjtConDataField.mjCONDATA_FOUND)
    force = 1 << int(mujoco.mjtConDataField.mjCONDATA_FORCE)
    reduce_netforce = 3  # MJCF reduce="netforce": one net force, world frame
    contact, geom, body = mujoco.mjtSensor.mjSENS_CONTACT, mujoco.mjtObj.mjOBJ_GEOM, mujoco.mjtObj.mjOBJ_BODY
    for leg in a1.LEG_NAMES:
        s = spec.add_sensor(name=f"{leg}_foot_contact", type=contact, objtype=geom, objname=f"{leg}_foot")
        s.intprm = [found | force, reduce_netforce, 1]
    for name in a1.NON_FOOT_COLLISION_GEOMS:  # body1=name: that body's geoms (feet are bodies of their own)
        s = spec.add_sensor(name=f"{name}_collision", type=contact, objtype=body, objname=name)
        s.intprm = [found, 0, 1]
