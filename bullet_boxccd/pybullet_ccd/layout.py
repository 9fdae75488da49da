"""Named columns of the core's per-frame state rows and per-box path rows.

The C++ side names the same columns (``FrameState`` and ``PathRow`` in
``_core/paths/step_path.hpp``); ``_core.layouts()`` reports them and a test checks that
both sides agree.
"""

from __future__ import annotations

__all__ = ["FRAME_STATE", "STATE_SIZE", "POSE", "POSITION", "ORIENTATION", "VELOCITY", "ANGULAR_VELOCITY",
           "TWIST", "PATH_ROW", "ROW_SIZE"]

# A frame's state after the step: centre-of-mass position, quaternion (x, y, z, w),
# linear and angular velocity, all world.
POSITION, ORIENTATION = slice(0, 3), slice(3, 7)
VELOCITY, ANGULAR_VELOCITY = slice(7, 10), slice(10, 13)
POSE, TWIST = slice(0, 7), slice(7, 13)
STATE_SIZE = 13
FRAME_STATE = {"position": POSITION, "orientation": ORIENTATION, "velocity": VELOCITY,
               "angular_velocity": ANGULAR_VELOCITY}

# A box on its path over the step (see _core/paths/step_path.hpp).
PATH_ROW = {"pose_after": slice(0, 16), "displacement": slice(16, 19), "axis": slice(19, 22),
            "angle": slice(22, 23), "box_in_frame": slice(23, 39), "half_extents": slice(39, 42)}
ROW_SIZE = 42
