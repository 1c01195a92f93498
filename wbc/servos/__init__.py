"""Servo deployment: AX-12A (Dynamixel Protocol 1.0) and SSC-32 buses, safety, ``wbc deploy``.

Modules: :mod:`.bus` (backend-independent interface, angle <-> command codec, bus budget),
:mod:`.dynamixel` (AX-12A on dynamixel-sdk), :mod:`.ssc32` (Lynxmotion SSC-32),
:mod:`.safety` (clamp, rate limit, soft start, watchdog), :mod:`.deploy` (playback and the
``wbc deploy`` command) and :mod:`.emulator` (pty emulators for tests and benchmarks; import
it explicitly, it needs a POSIX system).
"""

from .bus import BusBudget, Codec, DryRunBus, ServoBus, ServoStatus
from .deploy import (
    CallableSource,
    DeployConfig,
    Deployment,
    DeployResult,
    RecordingSource,
    TargetSource,
)
from .dynamixel import DynamixelBus
from .safety import GoalLimiter, Trip, Watchdog
from .ssc32 import Ssc32Bus, Ssc32Map

__all__ = [
    "BusBudget",
    "CallableSource",
    "Codec",
    "DeployConfig",
    "DeployResult",
    "Deployment",
    "DryRunBus",
    "DynamixelBus",
    "GoalLimiter",
    "RecordingSource",
    "ServoBus",
    "ServoStatus",
    "Ssc32Bus",
    "Ssc32Map",
    "TargetSource",
    "Trip",
    "Watchdog",
]
