"""A solved stance in words: forces per contact, depths in the soft bodies, margins to the limits.

What ``cbm check`` prints under its verdict. The numbers come from the solver's
result (``point_forces``, ``limits``) and from its independent verification
(``verification.measures``), never recomputed here.
"""

from __future__ import annotations

import numpy as np

from stances.deformable import RESOLVED_BALL_NODES

__all__ = ["stance_report"]


def stance_report(result, robot, stance):
    """Lines describing a solved stance's forces, depths and margins.

    Parameters
    ----------
    result : stances PostureResult
        The solve's answer, with its verification.
    robot : stances Robot
        Gives each robot surface's frame (to group the point forces).
    stance : environments Stance
        The contacts solved.

    Returns
    -------
    list of str
        Indented lines: ``forces`` (resultant on each robot surface, newtons,
        world frame), ``depths`` (indentation and largest strain of each soft
        body touched), ``slips`` (how far each soft print's link points lie off
        their nodes, and where they started) and ``margins`` (torque usage, joint clearance, closest
        distance, friction-cone margins, joints held on their margin).
    """
    lines = ["  forces on the robot (N, world frame):"]
    for contact in stance:
        frame = robot.surfaces[contact.robot_surface].frame
        total = np.sum([f.force for f in result.point_forces if f.frame == frame], axis=0) + np.zeros(3)
        lines.append(
            f"    {contact.robot_surface} on {contact.contact_print.surface}: {np.linalg.norm(total):.1f} N "
            f"(x {total[0]:.1f}, y {total[1]:.1f}, z {total[2]:.1f})"
        )
    measures = dict(getattr(result.verification, "measures", None) or {})
    bodies = [key[len("indentation of "):] for key in measures if key.startswith("indentation of ")]
    if bodies:
        lines.append("  depths in the soft bodies:")
        for name in bodies:
            strain = measures.get(f"largest strain of {name}")
            strained = "" if strain is None else f", largest strain {100 * strain:.2f} %"
            lines.append(f"    {name}: indented {1e3 * measures[f'indentation of {name}']:.2f} mm{strained}")
        for key in measures:
            if key.startswith("pressed nodes under "):
                label = key[len("pressed nodes under "):]
                count = measures[key]
                coarse = " (a contact smaller than the cells: its force depends on the mesh)" if 0 < count < RESOLVED_BALL_NODES else ""
                estimate = measures.get(f"ball force estimate under {label}")
                against = "" if estimate is None else (
                    f"; a continuous layer carries {estimate:.1f} N at its depth, the mesh "
                    f"{100 * measures[f'ball force error under {label}']:+.0f} %")
                lines.append(f"    {label}: {count} mesh node(s) pressed{coarse}{against}")
            elif key.startswith("layer force of "):
                label = key[len("layer force of "):]
                strain = measures.get(f"strain under {label}")
                strained = "" if strain is None else f", strains it {100 * strain:.2f} % (its converged field)"
                lines.append(f"    {label}: sinks {1e3 * measures[f'sinking of {label}']:.2f} mm, "
                             f"{measures[key]:.1f} N by its layer's law{strained}")
    slips = getattr(result, "slips", None) or {}
    held = getattr(result, "held_slips", None) or {}
    if slips:
        lines.append("  slips of the soft prints (link points over their nodes):")
        for surface, slip in slips.items():
            start = "from rest" if surface not in held else (
                f"from {1e3 * held[surface].largest():.2f} mm where the stance before left it")
            lines.append(f"    {surface} on {slip.body}: up to {1e3 * slip.largest():.2f} mm, {start}")
    lines.append("  margins:")
    limits = result.limits or {}
    if "torque_usage" in limits:
        lines.append(f"    largest torque: {100 * limits['torque_usage']:.1f} % of the limit of {limits['torque_joint']}")
    if "joint_clearance" in limits:
        lines.append(
            f"    closest joint limit: {100 * limits['joint_clearance']:.1f} % of the range of {limits['clearance_joint']}"
        )
    if "closest_distance" in measures:
        lines.append(f"    closest collision distance: {1e3 * measures['closest_distance']:.1f} mm")
    for key in sorted(measures):
        if key.startswith("cone margin"):
            lines.append(f"    {key}: {measures[key]:.1f} N")
    for item in limits.get("at_margin", ()):
        lines.append(f"    on its margin: {item}")
    return lines
