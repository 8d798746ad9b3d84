"""`testbench aircraft list|trim|modes|design`: the vehicle models, their trim, linear modes and
the fixed-wing autopilot gains designed on them."""

from __future__ import annotations

import json
import math
import os


def register(subparsers) -> None:
    p = subparsers.add_parser("aircraft", help="aircraft models: list, trim, linear modes, autopilot gain design")
    sub = p.add_subparsers(dest="aircraft_cmd", required=True)

    ls = sub.add_parser("list", help="list the project's models and those bundled with JSBSim")
    ls.set_defaults(handler=_list)

    for name, helptext, handler in (
        ("trim", "trim a model with JSBSim's trim (fixed wing: straight flight; multirotor: hover, --airspeed 0)", _trim),
        ("modes", "trim, linearise and print the longitudinal and lateral modes", _modes),
    ):
        c = sub.add_parser(name, help=helptext)
        c.add_argument("name", help="aircraft name (see `testbench aircraft list`)")
        c.add_argument("--airspeed", type=float, required=True, help="true airspeed, m/s")
        c.add_argument("--altitude", type=float, required=True, help="altitude above mean sea level, m")
        c.add_argument("--flight-path-deg", type=float, default=0.0, help="climb angle, deg (default 0)")
        c.add_argument("--json", metavar="FILE", default=None, help="also write the result as JSON to FILE")
        c.set_defaults(handler=handler)

    d = sub.add_parser("design", help="design a fixed wing's autopilot gains on its linear model (LQR/LQI, "
                                      "control.design) and print them as a gains.py entry")
    d.add_argument("name", help="fixed-wing aircraft name (see `testbench aircraft list`)")
    d.add_argument("--airspeed", type=float, default=25.0, help="design airspeed, m/s (default 25)")
    d.add_argument("--altitude", type=float, default=800.0, help="design altitude above mean sea level, m (default 800)")
    d.add_argument("--json", metavar="FILE", default=None, help="also write the design report (closed-loop poles, bandwidths) as JSON")
    d.set_defaults(handler=_design)


def _list(args) -> int:
    from testbench.dynamics.catalog import aircraft_meta, bundled_aircraft, project_aircraft

    print("project models (aircraft/):")
    for name in project_aircraft():
        meta = aircraft_meta(name)
        print(f"  {name:16s} {meta.get('kind', '?'):11s} {meta.get('mass_kg', '?')} kg  {meta.get('citation', '')}")
    print("bundled with JSBSim:")
    names = bundled_aircraft()
    for i in range(0, len(names), 8):
        print("  " + "  ".join(names[i:i + 8]))
    return 0


def _trim(args) -> int:
    from testbench.dynamics.trim import trim

    t = trim(args.name, args.airspeed, args.altitude, flight_path_deg=args.flight_path_deg)
    print(f"{t.aircraft} ({t.kind}) trimmed at {t.airspeed_mps:g} m/s, {t.altitude_m:g} m, "
          f"flight path {math.degrees(t.flight_path_rad):g} deg")
    print(f"  alpha {math.degrees(t.alpha_rad):8.3f} deg   theta {math.degrees(t.theta_rad):8.3f} deg   "
          f"phi {math.degrees(t.phi_rad):8.3f} deg   beta {math.degrees(t.beta_rad):8.4f} deg")
    print(f"  throttle {t.throttle_norm:.4f}   elevator {t.elevator_norm:+.4f}   aileron {t.aileron_norm:+.4f}   "
          f"rudder {t.rudder_norm:+.4f}  (normalised commands)")
    print(f"  residuals: |udot,vdot,wdot| <= {t.max_linear_residual_mps2:.2e} m/s^2, "
          f"|pdot,qdot,rdot| <= {t.max_angular_residual_rps2:.2e} rad/s^2")
    _write_json(args.json, t.to_dict())
    return 0


def _modes(args) -> int:
    from testbench.dynamics.linear import linearize

    lm = linearize(args.name, args.airspeed, args.altitude, flight_path_deg=args.flight_path_deg)
    t = lm.trim
    print(f"{t.aircraft} at {t.airspeed_mps:g} m/s, {t.altitude_m:g} m: alpha {math.degrees(t.alpha_rad):.2f} deg, "
          f"throttle {t.throttle_norm:.3f}, elevator {t.elevator_norm:+.3f}")
    head = f"  {'mode':13s} {'axis':13s} {'eigenvalue (1/s)':>22s} {'omega_n rad/s':>13s} {'zeta':>7s} {'tau s':>8s} {'period s':>9s}  stable"
    print(head)
    print("  " + "-" * (len(head) - 2))
    for m in lm.modes:
        eig = f"{m.eigenvalue_real:+.4f}" + (f" +/- {m.eigenvalue_imag:.4f}j" if m.eigenvalue_imag else "")
        period = f"{m.period_s:9.2f}" if m.period_s is not None else f"{'-':>9s}"
        note = "yes" if m.stable else f"NO (doubles in {m.time_to_double_s:.1f} s)" if m.time_to_double_s else "NO"
        print(f"  {m.name:13s} {m.axis:13s} {eig:>22s} {m.natural_frequency_rps:13.4f} {m.damping_ratio:7.3f} "
              f"{m.time_constant_s:8.3f} {period}  {note}")
    _write_json(args.json, lm.to_dict())
    return 0


def _design(args) -> int:
    from testbench.control.design import design_fixed_wing, gains_literal

    res = design_fixed_wing(args.name, args.airspeed, args.altitude)
    print(gains_literal(res.gains, args.name), end="")
    _write_json(args.json, res.report)
    return 0


def _write_json(path: str | None, payload: dict) -> None:
    if not path:
        return
    folder = os.path.dirname(os.path.abspath(path))
    os.makedirs(folder, exist_ok=True)
    with open(path, "w", encoding="utf-8") as fh:
        json.dump(payload, fh, indent=2, allow_nan=False, default=_jsonable)
    print(f"wrote {path}")


def _jsonable(x):
    if isinstance(x, complex):
        return [x.real, x.imag]
    raise TypeError(f"not JSON serialisable: {type(x).__name__}")
