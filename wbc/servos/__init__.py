"""Servo deployment: AX-12A (Dynamixel Protocol 1.0) and SSC-32 buses, safety, playback.

Modules: :mod:`.bus` (backend-independent interface, angle <-> command codec, bus budget),
:mod:`.protocol1` (the AX-12A's control table and Protocol 1.0 packets), :mod:`.dynamixel`
(AX-12A on dynamixel-sdk), :mod:`.protocol2` (X-series, Protocol 2.0), :mod:`.ssc32`
(Lynxmotion SSC-32), :mod:`.portlock` (one owner per port), :mod:`.safety` (clamp, rate limit,
soft start, watchdog, health schedule), :mod:`.sources` (targets to play), :mod:`.config`
(a deployment's settings), :mod:`.playback` (the deployment and its safe stop), :mod:`.plan`
(bus budget and fault bound), :mod:`.connect` (a robot's bus, its servo map checked) and
:mod:`.emulator` (pty emulators for tests and benchmarks; import it explicitly, it needs a
POSIX system). The ``wbc deploy`` command is :mod:`wbc.cli.deploy`.
"""

from .bus import BusBudget, Codec, DryRunBus, ServoBus, ServoStatus
from .config import DeployConfig
from .dynamixel import DynamixelBus
from .playback import Deployment, DeployResult
from .safety import GoalLimiter, HealthSchedule, Trip, Watchdog
from .sources import CallableSource, RecordingSource, TargetSource
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
    "HealthSchedule",
    "RecordingSource",
    "ServoBus",
    "ServoStatus",
    "Ssc32Bus",
    "Ssc32Map",
    "TargetSource",
    "Trip",
    "Watchdog",
]
