"""Writes ``diffdrive_arm.urdf``: the differential-drive robot with a simple arm and gripper.

The base is ``diffdrive.urdf`` unchanged (read from this folder, so the two
robots share one chassis) plus a second frictionless caster at the front (the
arm's weight ahead of the wheel axle would otherwise tip the robot forward,
which the rear caster alone cannot stop). The arm is our own simple cylindrical
manipulator of plausible public-fact-like dimensions (a mobile-manipulator add-on
of about 2.5 kg):

- ``arm_lift``: a prismatic joint along the chassis z axis on a column 5 cm
  ahead of the axle, carrying the gripper centre at ``z = LIFT_BASE_Z + q``;
- ``arm_yaw``: a revolute joint about that vertical axis;
- ``arm_extend``: a prismatic joint along the turned x axis; ``q`` is the
  horizontal distance of the gripper centre from the column axis;
- ``left_finger`` / ``right_finger``: two parallel fingers sliding along the
  turned y axis, ``q`` = distance of each finger's centre from the gripper centre.

So the gripper centre in the chassis frame is, in closed form,
``(COLUMN_X + e cos(yaw), e sin(yaw), LIFT_BASE_Z + lift)`` (see
``repertoire.systems.kitchen_actions.arm_forward``). Only the fingers collide
(the palm and the bar are visual), so the fingers alone touch the cup.

Masses and inertias come from the primitive shapes (solid boxes and cylinders),
computed with the helpers of ``models/arm7/generate.py``. The committed file must
equal what this script writes (``tests/test_kitchen_model.py`` checks that)::

    .venv/bin/python models/diffdrive/generate.py
"""

from pathlib import Path

from repertoire.models.arm7.generate import box_inertia, cylinder_inertia

HERE = Path(__file__).resolve().parent

COLUMN_X = 0.05  # column axis ahead of the wheel axle [m]
COLUMN_BASE_Z = 0.16  # column foot on the top plate (chassis frame) [m]
COLUMN_HEIGHT = 0.85  # [m]
LIFT_BASE_Z = COLUMN_BASE_Z  # gripper centre height at lift = 0 [m]
LIFT_RANGE = (0.30, 0.80)  # [m]
YAW_RANGE = (-1.7, 1.7)  # [rad]
EXTEND_RANGE = (0.25, 0.85)  # gripper centre from the column axis [m]
FINGER_RANGE = (0.03, 0.08)  # finger centre from the gripper centre [m]
FINGER_SIZE = (0.03, 0.02, 0.08)  # finger box (x, y, z) [m]
FINGER_FRICTION = 1.0
FRONT_CASTER_X = 0.17  # [m]
CASTER_RADIUS = 0.038  # as the rear caster of diffdrive.urdf [m]
CASTER_Z = -0.0595  # as the rear caster of diffdrive.urdf [m]

MASS = {"column": 1.0, "carriage": 0.4, "turret": 0.2, "slide": 0.5, "finger": 0.08}


def _f(x: float) -> str:
    """A number as URDF text (9 significant digits, no trailing noise)."""
    return f"{x:.9g}"


def _v(v) -> str:
    return " ".join(_f(x) for x in v)


def _inertial(mass: float, com, moments) -> str:
    ixx, iyy, izz = moments
    return (
        f'    <inertial>\n      <origin xyz="{_v(com)}"/>\n      <mass value="{_f(mass)}"/>\n'
        f'      <inertia ixx="{_f(ixx)}" ixy="0" ixz="0" iyy="{_f(iyy)}" iyz="0"'
        f' izz="{_f(izz)}"/>\n'
        "    </inertial>\n"
    )


def _visual(name: str, geometry: str, xyz, rgba, rpy=(0, 0, 0)) -> str:
    return (
        f'    <visual name="{name}">\n      <origin xyz="{_v(xyz)}" rpy="{_v(rpy)}"/>\n'
        f"      <geometry>{geometry}</geometry>\n"
        f'      <material><color rgba="{_v(rgba)}"/></material>\n    </visual>\n'
    )


def _collision(name: str, geometry: str, xyz, mu: float) -> str:
    return (
        f'    <collision name="{name}">\n      <origin xyz="{_v(xyz)}"/>\n'
        f"      <geometry>{geometry}</geometry>\n      <drake:proximity_properties>\n"
        f'        <drake:mu_dynamic value="{_f(mu)}"/>\n'
        f'        <drake:mu_static value="{_f(mu)}"/>\n'
        "      </drake:proximity_properties>\n    </collision>\n"
    )


def _box(size) -> str:
    return f'<box size="{_v(size)}"/>'


def _cylinder(radius: float, length: float) -> str:
    return f'<cylinder radius="{_f(radius)}" length="{_f(length)}"/>'


def _joint(name, kind, parent, child, xyz, axis, limits, effort, velocity) -> str:
    return (
        f'  <joint name="{name}" type="{kind}">\n    <parent link="{parent}"/>\n'
        f'    <child link="{child}"/>\n    <origin xyz="{_v(xyz)}"/>\n'
        + (f'    <axis xyz="{_v(axis)}"/>\n' if axis else "")
        + (
            f'    <limit lower="{_f(limits[0])}" upper="{_f(limits[1])}" effort="{_f(effort)}" '
            f'velocity="{_f(velocity)}"/>\n    <dynamics damping="0.5"/>\n'
            if limits
            else ""
        )
        + "  </joint>\n"
    )


def _transmission(joint: str) -> str:
    return (
        f'  <transmission type="SimpleTransmission" name="{joint}_transmission">\n'
        f'    <actuator name="{joint}_motor"/>\n    <joint name="{joint}"/>\n'
        "    <mechanicalReduction>1</mechanicalReduction>\n  </transmission>\n"
    )


def _link(name: str, body: str) -> str:
    return f'  <link name="{name}">\n{body}  </link>\n'


def arm_parts() -> str:
    """The arm's links, joints and transmissions as URDF text."""
    grey, dark, blue = (0.7, 0.7, 0.72, 1), (0.2, 0.2, 0.22, 1), (0.15, 0.35, 0.8, 1)
    col_r = 0.025
    column = _link(
        "arm_column",
        _inertial(
            MASS["column"],
            (0, 0, COLUMN_HEIGHT / 2),
            cylinder_inertia(MASS["column"], col_r, COLUMN_HEIGHT),
        )
        + _visual("column", _cylinder(col_r, COLUMN_HEIGHT), (0, 0, COLUMN_HEIGHT / 2), grey),
    )
    carriage_size = (0.08, 0.08, 0.06)
    carriage = _link(
        "arm_carriage",
        _inertial(MASS["carriage"], (0, 0, 0), box_inertia(MASS["carriage"], carriage_size))
        + _visual("carriage", _box(carriage_size), (0, 0, 0), dark),
    )
    turret = _link(
        "arm_turret",
        _inertial(MASS["turret"], (0, 0, 0), cylinder_inertia(MASS["turret"], 0.045, 0.02))
        + _visual("turret", _cylinder(0.045, 0.02), (0, 0, 0.04), dark),
    )
    # slide frame origin = gripper centre; the bar runs behind it to the palm.
    bar_size, palm_size = (0.6, 0.03, 0.03), (0.02, 0.18, 0.04)
    bar_x, palm_x = -0.065 - bar_size[0] / 2, -0.065
    m_bar, m_palm = MASS["slide"] * 0.7, MASS["slide"] * 0.3
    com_x = (m_bar * bar_x + m_palm * palm_x) / MASS["slide"]
    ib, ip = box_inertia(m_bar, bar_size), box_inertia(m_palm, palm_size)
    slide_moments = (
        ib[0] + ip[0],
        ib[1] + ip[1] + m_bar * (bar_x - com_x) ** 2 + m_palm * (palm_x - com_x) ** 2,
        ib[2] + ip[2] + m_bar * (bar_x - com_x) ** 2 + m_palm * (palm_x - com_x) ** 2,
    )
    slide = _link(
        "arm_slide",
        _inertial(MASS["slide"], (com_x, 0, 0), slide_moments)
        + _visual("bar", _box(bar_size), (bar_x, 0, 0.03), grey)
        + _visual("palm", _box(palm_size), (palm_x, 0, 0), dark),
    )
    fingers = ""
    for side in ("left", "right"):
        fingers += _link(
            f"{side}_finger",
            _inertial(MASS["finger"], (0, 0, 0), box_inertia(MASS["finger"], FINGER_SIZE))
            + _visual(f"{side}_finger", _box(FINGER_SIZE), (0, 0, 0), blue)
            + _collision(f"{side}_finger_collision", _box(FINGER_SIZE), (0, 0, 0), FINGER_FRICTION),
        )
    joints = (
        _joint(
            "arm_column_weld",
            "fixed",
            "chassis",
            "arm_column",
            (COLUMN_X, 0, COLUMN_BASE_Z),
            None,
            None,
            0,
            0,
        )
        + _joint(
            "arm_lift",
            "prismatic",
            "arm_column",
            "arm_carriage",
            (0, 0, 0),
            (0, 0, 1),
            LIFT_RANGE,
            150.0,
            0.5,
        )  # fmt: skip
        + _joint(
            "arm_yaw",
            "revolute",
            "arm_carriage",
            "arm_turret",
            (0, 0, 0),
            (0, 0, 1),
            YAW_RANGE,
            30.0,
            2.0,
        )  # fmt: skip
        + _joint(
            "arm_extend",
            "prismatic",
            "arm_turret",
            "arm_slide",
            (0, 0, 0),
            (1, 0, 0),
            EXTEND_RANGE,
            80.0,
            0.5,
        )  # fmt: skip
        + _joint(
            "left_finger",
            "prismatic",
            "arm_slide",
            "left_finger",
            (0, 0, 0),
            (0, 1, 0),
            FINGER_RANGE,
            20.0,
            0.2,
        )  # fmt: skip
        + _joint(
            "right_finger",
            "prismatic",
            "arm_slide",
            "right_finger",
            (0, 0, 0),
            (0, -1, 0),
            FINGER_RANGE,
            20.0,
            0.2,
        )  # fmt: skip
    )
    transmissions = "".join(
        _transmission(j)
        for j in ("arm_lift", "arm_yaw", "arm_extend", "left_finger", "right_finger")
    )
    return column + carriage + turret + slide + fingers + joints + transmissions


def front_caster() -> str:
    """The front caster's visual and collision (inside the chassis link)."""
    sphere = f'<sphere radius="{_f(CASTER_RADIUS)}"/>'
    xyz = (FRONT_CASTER_X, 0, CASTER_Z)
    return _visual("front_caster_visual", sphere, xyz, (0.2, 0.2, 0.2, 1)) + _collision(
        "front_caster_collision", sphere, xyz, 0.0
    )


def diffdrive_arm_urdf() -> str:
    """The text of ``diffdrive_arm.urdf``."""
    base = (HERE / "diffdrive.urdf").read_text()
    start = base.index('<robot name="diffdrive"')
    body = base[start:].replace('<robot name="diffdrive"', '<robot name="diffdrive_arm"', 1)
    chassis_end = body.index("  </link>")
    body = body[:chassis_end] + front_caster() + body[chassis_end:]
    end = body.rindex("</robot>")
    header = (
        '<?xml version="1.0"?>\n<!-- GENERATED by models/diffdrive/generate.py from diffdrive.urdf;'
        " do not edit.\n     repertoire diffdrive_arm: the diffdrive robot with a front caster and"
        " a lift / yaw /\n     extend arm with two parallel fingers (see generate.py). -->\n"
    )
    return header + body[:end] + arm_parts() + "</robot>\n"


def generated_files() -> dict[str, str]:
    """File name (relative to ``models/diffdrive``) -> text."""
    return {"diffdrive_arm.urdf": diffdrive_arm_urdf()}


def main() -> None:
    """Writes every generated file next to this script."""
    for name, text in generated_files().items():
        (HERE / name).write_text(text)
        print(f"wrote {HERE / name}")


if __name__ == "__main__":
    main()
