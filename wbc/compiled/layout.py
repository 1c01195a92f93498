"""The spec table shared by the plans (Python) and the row kernels (numba): task kinds and
column meanings. No numba import here, so that plans can be inspected without it."""

# task kinds (spec column KIND)
COM, POSITION, ORIENTATION, POSE, POSTURE, DAMPING, SWING_AXES, TORSO_AXIS = range(8)
# spec columns: kind, frame slot (-1: none), target offset, first output row, first mask index,
# number of output rows
KIND, FRAME, TARGET, ROW, SEL, ROWS = range(6)
SPEC_COLUMNS = 6
