"""Load a stack file and step it: the same controller as ``wbc walk --stack cj_com``."""

import wbc.stacks
from wbc import load_robot

robot = load_robot("bioloid")
q = robot.configuration("walk_ready")
control = wbc.stacks.load_stack("cj_com", robot, q)  # tasks/cj_com.toml
print(control.name, type(control.solver).__name__, [t.name for t in control.stack.tasks()])
q = control.solver.step(q, dt=0.01)
