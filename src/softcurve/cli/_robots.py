"""Robot and actuator for the statics and control commands: a TOML file or the paper's robot.

Shared by ``softcurve equilibria`` and ``softcurve codegen``. Without a file the robot
is the preset ifac2020; its bellows geometry is not published, so the actuator is the
illustrative one of ``--bellows`` (default :data:`ILLUSTRATIVE_BELLOWS`).
"""

from __future__ import annotations

ILLUSTRATIVE_BELLOWS = (0.012, 2.0e-4, 6.0e4)
"""``(distance [m], area [m^2], p_max [Pa])`` used when no file gives the actuation."""


def add_arguments(parser) -> None:
    parser.add_argument(
        "config",
        nargs="?",
        help="TOML file with the robot (and [actuation], [environment] tables); "
        "default: preset ifac2020",
    )
    parser.add_argument(
        "--bellows",
        nargs=3,
        type=float,
        metavar=("RHO", "AREA", "P_MAX"),
        help="three bellows per segment at distance RHO [m] with area AREA [m^2] and upper "
        "bound P_MAX [Pa] (default, without an [actuation] table: "
        f"{' '.join(map(str, ILLUSTRATIVE_BELLOWS))}, illustrative)",
    )


def robot_and_actuator(args):
    """``(robot, actuator, environment)`` from the parsed arguments (the environment of
    the file's ``[environment]`` table, or None)."""
    from softcurve.description import presets
    from softcurve.description.bellows import PneumaticActuator

    robot, actuator, environment = presets.ifac2020(), None, None
    if args.config is not None:
        from softcurve.scenarios.config import load_config

        scenario = load_config(args.config)
        robot, actuator, environment = scenario.robot, scenario.actuator(), scenario.environment
    if actuator is None or args.bellows is not None:
        rho, area, p_max = args.bellows or ILLUSTRATIVE_BELLOWS
        actuator = PneumaticActuator.three_bellows(
            distance=rho, area=area, p_max=p_max, n_segments=robot.n_segments
        )
    return robot, actuator, environment
