"""``bfsitl vehicle``: the quads the embedded physics flies (``list``), and one in full with
the figures the physics derives from it (``show``)."""

from __future__ import annotations

import argparse
import json
import math
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from bfsitl.physics.params import QuadParams

EXIT_OK = 0


def add_vehicle_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    vehicle = sub.add_parser(
        "vehicle",
        help="the simulated quads: list them, show one",
        description="The quads bfsitl's embedded physics flies: IRIS (Gazebo's, the default) "
        "and the profiles shipped with bfsitl; `--vehicle NAME|FILE.toml` picks one wherever "
        "a flight starts (docs/vehicles.md).",
    )
    actions = vehicle.add_subparsers(dest="vehicle_action", required=True, metavar="ACTION")
    listing = actions.add_parser("list", help="the shipped vehicles, with their key figures")
    listing.add_argument("--json", action="store_true", help="one JSON object per vehicle")
    listing.set_defaults(func=cmd_vehicle_list)
    show = actions.add_parser(
        "show", help="one vehicle: its profile and what the physics makes of it"
    )
    show.add_argument("vehicle", metavar="NAME|FILE", help="a shipped vehicle or a profile file")
    show.add_argument("--json", action="store_true", help="as JSON")
    show.set_defaults(func=cmd_vehicle_show)


def figures(name: str) -> dict[str, Any]:
    """What the physics makes of vehicle ``name`` (a name or a file)."""
    from bfsitl.vehicles import hover_throttle_us, load_vehicle

    quad = load_vehicle(name)
    return {
        "name": quad.name,
        "mass_g": round(quad.mass_kg * 1000.0, 1),
        "thrust_to_weight": round(_thrust_to_weight(quad), 2),
        "hover_command": round(quad.hover_command, 4),
        "hover_throttle_us": round(hover_throttle_us(quad)),
        "hover_rotor_speed_rpm": round(quad.hover_rotor_speed_rad_s * 60.0 / math.tau),
        "motor_time_constant_ms": round(quad.motor_time_constant_s * 1000.0, 2),
        "inertia_kg_m2": list(quad.inertia_kg_m2),
    }


def _thrust_to_weight(quad: QuadParams) -> float:
    """Four rotors' thrust at the top steady speed over the weight."""
    top_rad_s = min(quad.steady_rotor_speed_rad_s(1.0), quad.max_rotor_speed_rad_s)
    return 4.0 * quad.thrust_coefficient_n_per_rad2_s2 * top_rad_s**2 / quad.weight_n


def cmd_vehicle_list(args: argparse.Namespace) -> int:
    from bfsitl.vehicles import DEFAULT_VEHICLE, shipped_profiles, vehicle_names

    described = {name: spec.description for name, spec in shipped_profiles().items()}
    described[DEFAULT_VEHICLE] = "Gazebo's IRIS (the tutorial's quad; the default)"
    rows = [figures(name) | {"description": described[name]} for name in vehicle_names()]
    if args.json:
        for row in rows:
            print(json.dumps(row))
        return EXIT_OK
    print(f"{'NAME':18} {'MASS':>7} {'T/W':>5} {'HOVER':>7} {'MOTOR':>7}  DESCRIPTION")
    for row in rows:
        print(
            f"{row['name']:18} {row['mass_g']:5.0f} g {row['thrust_to_weight']:5.1f} "
            f"{row['hover_throttle_us']:4d} us {row['motor_time_constant_ms']:4.1f} ms  "
            f"{row['description']}"
        )
    return EXIT_OK


def cmd_vehicle_show(args: argparse.Namespace) -> int:
    from bfsitl.vehicles import DEFAULT_VEHICLE, profile_text, read_profile, shipped_profiles

    derived = figures(args.vehicle)
    shipped = shipped_profiles()
    if args.vehicle in shipped:
        text = profile_text(shipped[args.vehicle])
    elif args.vehicle == DEFAULT_VEHICLE:
        text = "# Gazebo's IRIS: bfsitl.physics.params.IRIS (each figure's source is there)\n"
    else:
        from pathlib import Path

        text = profile_text(read_profile(Path(args.vehicle)))
    if args.json:
        print(json.dumps({"figures": derived, "profile": text}))
        return EXIT_OK
    print(text.rstrip())
    print()
    print("# what the physics makes of it")
    for key, value in derived.items():
        print(f"# {key} = {value}")
    return EXIT_OK
