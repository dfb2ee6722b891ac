"""LeRobot robots on cps (see README.md): `cps_franka`, a Franka over the FCI, and
`cps_dynamics`, cps's simulated FR3. LeRobot imports this package by its name and finds
each robot's class here from its config's name (`CpsFrankaConfig` -> `CpsFranka`)."""

from .config import CpsDynamicsConfig, CpsFrankaConfig, CpsRobotConfig
from .robot import CpsDynamics, CpsFranka, CpsRobot

__all__ = ["CpsDynamics", "CpsDynamicsConfig", "CpsFranka", "CpsFrankaConfig", "CpsRobot", "CpsRobotConfig"]
