"""A three-level stack built in Python: hard contact, CoM and swing foot, torso and posture."""

import numpy as np

from wbc import Kinematics, load_robot
from wbc.solvers import HierarchicalQP, TaskStack
from wbc.tasks import ComTask, ContactTask, FrameOrientationTask, FramePoseTask, PostureTask

robot = load_robot("bioloid")
q = robot.configuration("walk_ready")  # standing, left sole flat at z = 0
kin = Kinematics(robot, q)

stack = TaskStack(robot)  # joint position and servo velocity limits are included
contact = ContactTask(robot, "l_sole")
stack.add(contact, level=0, hard=True)
contact.make_contact(kin)  # hold the left sole where it is now
com = ComTask(robot, kin.com)
stack.add(com, level=1, weight=1000.0)
swing = FramePoseTask(robot, "r_sole", name="swing")
stack.add(swing, level=1, weight=100.0)
swing.set_target_from(kin)  # keep the right sole where it is
torso = kin.placement(robot.frame_id("torso")).rotation
stack.add(FrameOrientationTask(robot, "torso", torso), level=2)
stack.add(PostureTask(robot, q), level=2, weight=0.01)

solver = HierarchicalQP(stack, backend="daqp")  # or WeightedQP(stack, "proxqp")
start = kin.com.copy()
for k in range(100):
    com.set_target(start + np.array([0.0, 0.0002 * k, 0.0]))  # 0.2 mm per tick to the left
    q = solver.step(q, dt=0.01)  # one QP per 10 ms control tick
errors = stack.errors()  # task name -> error e = x* - x of the last solve (m or rad)
print({name: float(np.abs(e).max()) for name, e in errors.items()})
