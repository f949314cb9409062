"""Writes ``arm7.urdf`` and the world-object SDF files of ``models/arm7/``.

The model files are generated so that every mass and inertia is computed from
the primitive shape it stands for (solid cylinders, boxes, spheres, thin
shells) instead of being typed in by hand. The committed files must equal what
this script writes; ``tests/test_arm_model.py`` checks that. Run it after a
change with::

    .venv/bin/python models/arm7/generate.py

Dimensions follow a human arm / the Sarcos Master-Slave arm class: upper arm
0.30 m (shoulder centre to elbow axis), forearm 0.30 m (elbow axis to wrist
centre), a spherical shoulder and a spherical wrist, and a three-finger hand
(thumb opposing two fingers, one revolute DOF each).
"""

import dataclasses
import math
from pathlib import Path

HERE = Path(__file__).resolve().parent

# ----------------------------------------------------------------------------- dimensions
SHOULDER_HEIGHT = 1.10  # shoulder centre above the base frame (floor) [m]
SHOULDER_TO_HR = 0.06  # humeral-rotation joint below the shoulder centre [m]
UPPER_ARM = 0.30  # shoulder centre to elbow axis [m]
FOREARM = 0.30  # elbow axis to wrist centre [m]
PALM_OFFSET = 0.08  # wrist centre to the palm face (origin of the `palm` frame) [m]
FINGER_BASE_Y = 0.055  # finger joints at +-0.055 m on the palm's closing axis [m]
FINGER_BASE_Z = 0.005  # finger joints 5 mm in front of the palm face [m]
FINGER_SPREAD_X = 0.025  # the two fingers sit at x = +-0.025 m, the thumb at x = 0 [m]
FINGER_LENGTH = 0.085  # finger joint to fingertip-sphere centre [m]
FINGER_RADIUS = 0.009  # finger capsule radius [m]
TIP_RADIUS = 0.011  # fingertip sphere radius [m]
TCP_OFFSET = 0.085  # palm face to the tool centre point (grasp centre) [m]
TORSO_Y = 0.22  # the base column stands 0.22 m to the left (+y) of the shoulder [m]

FINGER_FRICTION = 1.0
OBJECT_FRICTION = 0.8
TABLE_FRICTION = 0.6


@dataclasses.dataclass
class Inertia:
    """Mass, centre of mass and rotational inertia about the COM (link axes)."""

    mass: float
    com: tuple[float, float, float]
    ixx: float
    iyy: float
    izz: float


def cylinder_inertia(mass: float, radius: float, length: float, axis: str = "z") -> tuple:
    """Principal moments (ixx, iyy, izz) of a solid cylinder about its centre.

    Args:
        mass: mass [kg].
        radius: radius [m].
        length: length along ``axis`` [m].
        axis: ``"x"``, ``"y"`` or ``"z"``, the cylinder's axis.
    """
    axial = 0.5 * mass * radius**2
    transverse = mass * (3 * radius**2 + length**2) / 12.0
    return {
        "x": (axial, transverse, transverse),
        "y": (transverse, axial, transverse),
        "z": (transverse, transverse, axial),
    }[axis]


def box_inertia(mass: float, size: tuple[float, float, float]) -> tuple:
    """Principal moments (ixx, iyy, izz) of a solid box about its centre.

    Args:
        mass: mass [kg].
        size: edge lengths (x, y, z) [m].
    """
    x, y, z = size
    return (mass * (y**2 + z**2) / 12, mass * (x**2 + z**2) / 12, mass * (x**2 + y**2) / 12)


def sphere_inertia(mass: float, radius: float) -> tuple:
    """Principal moments of a solid sphere about its centre."""
    i = 0.4 * mass * radius**2
    return (i, i, i)


def combine(parts: list[tuple[float, tuple, tuple]]) -> Inertia:
    """Combines point-symmetric parts (mass, centre, principal moments) by parallel axes.

    Every part's principal axes are the link axes, so the products of inertia of
    the combination vanish when the centres share two coordinates; the parts
    used here are all placed so (products of inertia are dropped otherwise).

    Args:
        parts: list of (mass, centre (x, y, z), (ixx, iyy, izz) about the centre).
    """
    mass = sum(p[0] for p in parts)
    com = tuple(sum(p[0] * p[1][k] for p in parts) / mass for k in range(3))
    ixx = iyy = izz = 0.0
    for m, c, (a, b, cc) in parts:
        dx, dy, dz = (c[k] - com[k] for k in range(3))
        ixx += a + m * (dy**2 + dz**2)
        iyy += b + m * (dx**2 + dz**2)
        izz += cc + m * (dx**2 + dy**2)
    return Inertia(mass, com, ixx, iyy, izz)


def _f(x: float) -> str:
    """Formats a number compactly and deterministically."""
    s = f"{x:.12g}"
    return "0" if s == "-0" else s


def _v(v) -> str:
    return " ".join(_f(x) for x in v)


# ----------------------------------------------------------------------------- URDF pieces
def _inertial(inertia: Inertia) -> str:
    return (
        f'    <inertial>\n      <origin xyz="{_v(inertia.com)}" rpy="0 0 0"/>\n'
        f'      <mass value="{_f(inertia.mass)}"/>\n'
        f'      <inertia ixx="{_f(inertia.ixx)}" ixy="0" ixz="0" iyy="{_f(inertia.iyy)}" '
        f'iyz="0" izz="{_f(inertia.izz)}"/>\n    </inertial>\n'
    )


def _geometry(shape: str, dims: tuple) -> str:
    if shape == "cylinder":
        return f'<cylinder radius="{_f(dims[0])}" length="{_f(dims[1])}"/>'
    if shape == "capsule":
        return f'<drake:capsule radius="{_f(dims[0])}" length="{_f(dims[1])}"/>'
    if shape == "box":
        return f'<box size="{_v(dims)}"/>'
    if shape == "sphere":
        return f'<sphere radius="{_f(dims[0])}"/>'
    raise ValueError(shape)


_RPY_FOR_AXIS = {"x": (0, math.pi / 2, 0), "y": (math.pi / 2, 0, 0), "z": (0, 0, 0)}


def _shape(
    kind: str,
    name: str,
    shape: str,
    dims: tuple,
    xyz: tuple,
    axis: str = "z",
    material: str = "",
    friction: float | None = None,
) -> str:
    rpy = _RPY_FOR_AXIS[axis]
    out = f'    <{kind} name="{name}">\n      <origin xyz="{_v(xyz)}" rpy="{_v(rpy)}"/>\n'
    out += f"      <geometry>{_geometry(shape, dims)}</geometry>\n"
    if kind == "visual" and material:
        out += f'      <material name="{material}"/>\n'
    if kind == "collision" and friction is not None:
        out += (
            "      <drake:proximity_properties>\n"
            f'        <drake:mu_dynamic value="{_f(friction)}"/>\n'
            f'        <drake:mu_static value="{_f(friction)}"/>\n'
            "      </drake:proximity_properties>\n"
        )
    return out + f"    </{kind}>\n"


def _both(
    name: str,
    shape: str,
    dims: tuple,
    xyz: tuple,
    axis: str = "z",
    material: str = "grey",
    collide: bool = True,
    friction: float | None = None,
) -> str:
    out = _shape("visual", name, shape, dims, xyz, axis, material)
    if collide:
        out += _shape("collision", name, shape, dims, xyz, axis, friction=friction)
    return out


@dataclasses.dataclass
class JointSpec:
    """One actuated revolute joint of the arm or hand."""

    name: str
    parent: str
    child: str
    xyz: tuple
    rpy: tuple
    axis: tuple
    lower: float
    upper: float
    effort: float
    velocity: float
    damping: float


def _arm_joint(
    name: str,
    parent: str,
    child: str,
    xyz: tuple,
    axis: tuple,
    limits: tuple[float, float],
    effort: float,
    velocity: float,
    damping: float,
) -> JointSpec:
    """An arm joint: child frame aligned with the parent's (rpy = 0)."""
    return JointSpec(name, parent, child, xyz, (0, 0, 0), axis, *limits, effort, velocity, damping)


def _finger_joint(name: str, xyz: tuple, axis: tuple, effort: float) -> JointSpec:
    """A hand joint: frame aligned with the palm frame (rpy = pi about x from the hand)."""
    return JointSpec(
        name, "hand", f"{name}_link", xyz, (math.pi, 0, 0), axis, -0.4, 1.0, effort, 4.0, 0.005
    )


_FINGER_Z = -(PALM_OFFSET + FINGER_BASE_Z)

#: Arm joints (Sarcos naming: SFE, SAA, HR, EB, WR, WFE, WAA) then hand joints.
JOINTS: list[JointSpec] = [
    # name, parent, child, xyz, axis, (lower, upper), effort, velocity, damping
    _arm_joint(
        "shoulder_flexion",
        "base",
        "shoulder_link",
        (0, 0, SHOULDER_HEIGHT),
        (0, -1, 0),
        (-0.9, 2.8),
        120.0,
        2.5,
        1.0,
    ),
    _arm_joint(
        "shoulder_abduction",
        "shoulder_link",
        "shoulder_yoke",
        (0, 0, 0),
        (-1, 0, 0),
        (-0.4, 2.4),
        120.0,
        2.5,
        1.0,
    ),
    _arm_joint(
        "humeral_rotation",
        "shoulder_yoke",
        "upper_arm",
        (0, 0, -SHOULDER_TO_HR),
        (0, 0, 1),
        (-1.6, 1.6),
        60.0,
        3.0,
        0.5,
    ),
    _arm_joint(
        "elbow",
        "upper_arm",
        "forearm",
        (0, 0, -(UPPER_ARM - SHOULDER_TO_HR)),
        (0, -1, 0),
        (0.0, 2.6),
        80.0,
        3.0,
        0.5,
    ),
    _arm_joint(
        "wrist_rotation",
        "forearm",
        "wrist_link",
        (0, 0, -FOREARM),
        (0, 0, 1),
        (-1.6, 1.6),
        15.0,
        4.0,
        0.1,
    ),
    _arm_joint(
        "wrist_flexion",
        "wrist_link",
        "wrist_yoke",
        (0, 0, 0),
        (1, 0, 0),
        (-1.2, 1.2),
        15.0,
        4.0,
        0.1,
    ),
    _arm_joint(
        "wrist_abduction", "wrist_yoke", "hand", (0, 0, 0), (0, 1, 0), (-0.6, 0.6), 15.0, 4.0, 0.1
    ),
    _finger_joint("thumb", (0, FINGER_BASE_Y, _FINGER_Z), (-1, 0, 0), 4.0),
    _finger_joint("finger_1", (FINGER_SPREAD_X, -FINGER_BASE_Y, _FINGER_Z), (1, 0, 0), 2.0),
    _finger_joint("finger_2", (-FINGER_SPREAD_X, -FINGER_BASE_Y, _FINGER_Z), (1, 0, 0), 2.0),
]


def _links() -> dict[str, tuple[Inertia, str]]:
    """Every link's inertia and geometry (all link frames axis-aligned at q = 0)."""
    links: dict[str, tuple[Inertia, str]] = {}
    h = SHOULDER_HEIGHT
    col_h = h + 0.05
    links["base"] = (
        combine(
            [
                (30.0, (0, TORSO_Y, col_h / 2), cylinder_inertia(30.0, 0.08, col_h)),
                (3.0, (0, 0.14, h), box_inertia(3.0, (0.10, 0.16, 0.10))),
            ]
        ),
        _both("column", "cylinder", (0.08, col_h), (0, TORSO_Y, col_h / 2), material="dark")
        + _both("bracket", "box", (0.10, 0.16, 0.10), (0, 0.14, h), material="dark"),
    )
    links["shoulder_link"] = (
        combine([(2.0, (0, 0, 0), cylinder_inertia(2.0, 0.055, 0.10, "y"))]),
        _both("housing", "cylinder", (0.055, 0.10), (0, 0, 0), "y", "orange"),
    )
    links["shoulder_yoke"] = (
        combine([(1.2, (0, 0, -0.02), cylinder_inertia(1.2, 0.05, 0.08, "x"))]),
        _both("housing", "cylinder", (0.05, 0.08), (0, 0, -0.02), "x", "grey", collide=False),
    )
    ua = UPPER_ARM - SHOULDER_TO_HR
    links["upper_arm"] = (
        combine(
            [
                (3.0, (0, 0, -ua / 2), cylinder_inertia(3.0, 0.045, ua)),
                (0.5, (0, 0, -ua), cylinder_inertia(0.5, 0.05, 0.10, "y")),
            ]
        ),
        _both("tube", "cylinder", (0.045, ua - 0.05), (0, 0, -ua / 2 + 0.005), material="orange")
        + _both("elbow_housing", "cylinder", (0.05, 0.10), (0, 0, -ua), "y", "grey"),
    )
    links["forearm"] = (
        combine(
            [
                (2.0, (0, 0, -0.13), cylinder_inertia(2.0, 0.04, 0.26)),
                (0.3, (0, 0, -FOREARM + 0.02), cylinder_inertia(0.3, 0.035, 0.04)),
            ]
        ),
        _both("tube", "cylinder", (0.04, 0.22), (0, 0, -0.14), material="orange")
        + _both(
            "wrist_cuff",
            "cylinder",
            (0.035, 0.04),
            (0, 0, -FOREARM + 0.02),
            material="grey",
            collide=False,
        ),
    )
    links["wrist_link"] = (
        combine([(0.3, (0, 0, 0), cylinder_inertia(0.3, 0.03, 0.05, "x"))]),
        _both("knuckle", "cylinder", (0.03, 0.05), (0, 0, 0), "x", "dark", collide=False),
    )
    links["wrist_yoke"] = (
        combine([(0.3, (0, 0, 0), cylinder_inertia(0.3, 0.03, 0.05, "y"))]),
        _both("knuckle", "cylinder", (0.03, 0.05), (0, 0, 0), "y", "dark", collide=False),
    )
    palm_size = (0.08, 0.13, PALM_OFFSET - 0.02)
    palm_z = -(0.02 + PALM_OFFSET) / 2
    links["hand"] = (
        combine(
            [
                (0.1, (0, 0, -0.01), cylinder_inertia(0.1, 0.035, 0.02)),
                (0.6, (0, 0, palm_z), box_inertia(0.6, palm_size)),
            ]
        ),
        _both("cuff", "cylinder", (0.035, 0.02), (0, 0, -0.01), material="grey", collide=False)
        + _both(
            "palm", "box", palm_size, (0, 0, palm_z), material="skin", friction=FINGER_FRICTION
        ),
    )
    finger_mass, tip_mass = 0.06, 0.02
    seg = FINGER_LENGTH - 0.01
    finger = combine(
        [
            (finger_mass, (0, 0, seg / 2), cylinder_inertia(finger_mass, FINGER_RADIUS, seg)),
            (tip_mass, (0, 0, FINGER_LENGTH), sphere_inertia(tip_mass, TIP_RADIUS)),
        ]
    )
    for name in ("thumb_link", "finger_1_link", "finger_2_link"):
        links[name] = (
            finger,
            _both(
                "phalanx",
                "capsule",
                (FINGER_RADIUS, seg),
                (0, 0, seg / 2),
                material="skin",
                friction=FINGER_FRICTION,
            )
            + _both(
                "tip",
                "sphere",
                (TIP_RADIUS,),
                (0, 0, FINGER_LENGTH),
                material="tip",
                friction=FINGER_FRICTION,
            ),
        )
    return links


_MATERIALS = {
    "dark": (0.25, 0.25, 0.28, 1),
    "grey": (0.6, 0.6, 0.62, 1),
    "orange": (0.95, 0.55, 0.15, 1),
    "skin": (0.85, 0.75, 0.65, 1),
    "tip": (0.3, 0.3, 0.3, 1),
}


def arm7_urdf() -> str:
    """Returns the text of ``arm7.urdf``."""
    out = [
        '<?xml version="1.0"?>',
        "<!-- Generated by models/arm7/generate.py; edit that file, not this one. -->",
        "<!-- repertoire arm7: 7-DOF anthropomorphic arm (SFE, SAA, HR, EB, WR, WFE, WAA)",
        "     with a 3-DOF hand (thumb opposing two fingers). At q = 0 the arm hangs",
        "     straight down. Frames `palm` and `tcp`: +z approach (out of the palm),",
        "     +y closing direction of the thumb, +x along the two fingers' spread. -->",
        '<robot name="arm7" xmlns:drake="http://drake.mit.edu">',
    ]
    for name, rgba in _MATERIALS.items():
        out.append(f'  <material name="{name}"><color rgba="{_v(rgba)}"/></material>')
    for name, (inertia, geometry) in _links().items():
        out.append(f'  <link name="{name}">\n{_inertial(inertia)}{geometry}  </link>')
    for j in JOINTS:
        out.append(
            f'  <joint name="{j.name}" type="revolute">\n'
            f'    <parent link="{j.parent}"/>\n    <child link="{j.child}"/>\n'
            f'    <origin xyz="{_v(j.xyz)}" rpy="{_v(j.rpy)}"/>\n'
            f'    <axis xyz="{_v(j.axis)}"/>\n'
            f'    <limit lower="{_f(j.lower)}" upper="{_f(j.upper)}" effort="{_f(j.effort)}" '
            f'velocity="{_f(j.velocity)}"/>\n'
            f'    <dynamics damping="{_f(j.damping)}"/>\n  </joint>'
        )
    for j in JOINTS:
        out.append(
            f'  <transmission name="{j.name}_transmission">\n'
            "    <type>transmission_interface/SimpleTransmission</type>\n"
            f'    <joint name="{j.name}">'
            "<hardwareInterface>EffortJointInterface</hardwareInterface></joint>\n"
            f'    <actuator name="{j.name}_motor"><mechanicalReduction>1</mechanicalReduction>'
            "</actuator>\n  </transmission>"
        )
    palm_rpy = (math.pi, 0, 0)
    out.append(
        f'  <frame name="palm" link="hand" xyz="0 0 {_f(-PALM_OFFSET)}" rpy="{_v(palm_rpy)}"/>'
    )
    out.append(
        f'  <frame name="tcp" link="hand" xyz="0 0 {_f(-(PALM_OFFSET + TCP_OFFSET))}" '
        f'rpy="{_v(palm_rpy)}"/>'
    )
    out.append(
        f'  <frame name="shoulder" link="base" xyz="0 0 {_f(SHOULDER_HEIGHT)}" rpy="0 0 0"/>'
    )
    groups = {
        "shoulder_group": ("base", "shoulder_link", "shoulder_yoke", "upper_arm"),
        "elbow_group": ("upper_arm", "forearm"),
        "wrist_group": ("forearm", "wrist_link", "wrist_yoke", "hand"),
    }
    for group, members in groups.items():
        out.append(f'  <drake:collision_filter_group name="{group}">')
        out += [f'    <drake:member link="{m}"/>' for m in members]
        out.append(f'    <drake:ignored_collision_filter_group name="{group}"/>')
        out.append("  </drake:collision_filter_group>")
    out.append("</robot>")
    return "\n".join(out) + "\n"


# ----------------------------------------------------------------------------- objects (SDF)
def _sdf_inertial(inertia: Inertia) -> str:
    return (
        f"      <inertial>\n        <pose>{_v(inertia.com)} 0 0 0</pose>\n"
        f"        <mass>{_f(inertia.mass)}</mass>\n        <inertia><ixx>{_f(inertia.ixx)}</ixx>"
        f"<iyy>{_f(inertia.iyy)}</iyy><izz>{_f(inertia.izz)}</izz>"
        "<ixy>0</ixy><ixz>0</ixz><iyz>0</iyz></inertia>\n      </inertial>\n"
    )


def _sdf_geom(shape: str, dims: tuple) -> str:
    if shape == "cylinder":
        return f"<cylinder><radius>{_f(dims[0])}</radius><length>{_f(dims[1])}</length></cylinder>"
    if shape == "box":
        return f"<box><size>{_v(dims)}</size></box>"
    return f"<sphere><radius>{_f(dims[0])}</radius></sphere>"


def _sdf_visual(name: str, shape: str, dims: tuple, xyz: tuple, rgba: tuple) -> str:
    return (
        f'      <visual name="{name}">\n        <pose>{_v(xyz)} 0 0 0</pose>\n'
        f"        <geometry>{_sdf_geom(shape, dims)}</geometry>\n"
        f"        <material><diffuse>{_v(rgba)}</diffuse></material>\n      </visual>\n"
    )


def _sdf_collision(name: str, shape: str, dims: tuple, xyz: tuple, mu: float) -> str:
    return (
        f'      <collision name="{name}">\n        <pose>{_v(xyz)} 0 0 0</pose>\n'
        f"        <geometry>{_sdf_geom(shape, dims)}</geometry>\n"
        "        <drake:proximity_properties>"
        f"<drake:mu_dynamic>{_f(mu)}</drake:mu_dynamic>"
        f"<drake:mu_static>{_f(mu)}</drake:mu_static></drake:proximity_properties>\n"
        "      </collision>\n"
    )


def _foot_spheres(radius_ring: float, sphere_radius: float, count: int, mu: float) -> str:
    """Small spheres under a round object so it rests stably under point contact."""
    out = ""
    for k in range(count):
        a = 2 * math.pi * k / count
        xyz = (radius_ring * math.cos(a), radius_ring * math.sin(a), sphere_radius)
        out += _sdf_collision(f"foot_{k}", "sphere", (sphere_radius,), xyz, mu)
    return out


def _sdf_model(name: str, body: str, inertia: Inertia, geometry: str, frames: dict) -> str:
    out = (
        '<?xml version="1.0"?>\n'
        "<!-- Generated by models/arm7/generate.py; edit that file, not this one. -->\n"
        '<sdf version="1.7" xmlns:drake="http://drake.mit.edu">\n'
        f'  <model name="{name}">\n    <link name="{body}">\n'
        f"{_sdf_inertial(inertia)}{geometry}    </link>\n"
    )
    for frame, xyz in frames.items():
        out += (
            f'    <frame name="{frame}" attached_to="{body}"><pose>{_v(xyz)} 0 0 0</pose></frame>\n'
        )
    return out + "  </model>\n</sdf>\n"


# Object dimensions (public, everyday sizes) [m, kg].
CUP_RADIUS, CUP_HEIGHT, CUP_MASS = 0.035, 0.10, 0.15
BOTTLE_RADIUS, BOTTLE_BODY_HEIGHT, BOTTLE_HEIGHT, BOTTLE_MASS = 0.035, 0.19, 0.25, 0.5
COASTER_RADIUS, COASTER_THICKNESS, COASTER_MASS = 0.05, 0.006, 0.02
OBSTACLE_RADIUS, OBSTACLE_MASS = 0.06, 0.3
TABLE_SIZE = (0.80, 1.20, 0.04)
TABLE_HEIGHT = 0.75
FOOT_SPHERE = 0.003


def cup_sdf() -> str:
    """A red cup: thin wall (0.12 kg) + bottom (0.03 kg); origin at the bottom centre."""
    wall_m, bottom_m = 0.12, 0.03
    h, r = CUP_HEIGHT, CUP_RADIUS
    shell = (wall_m * (r**2 / 2 + h**2 / 12), wall_m * (r**2 / 2 + h**2 / 12), wall_m * r**2)
    inertia = combine(
        [
            (wall_m, (0, 0, h / 2), shell),
            (bottom_m, (0, 0, 0.003), cylinder_inertia(bottom_m, r, 0.006)),
        ]
    )
    body_len = h - FOOT_SPHERE
    geom = (
        _sdf_visual("body", "cylinder", (r, h), (0, 0, h / 2), (0.85, 0.1, 0.1, 1))
        + _sdf_visual(
            "opening", "cylinder", (r - 0.003, 0.002), (0, 0, h - 0.0005), (0.35, 0.02, 0.02, 1)
        )
        + _sdf_collision(
            "body", "cylinder", (r, body_len), (0, 0, FOOT_SPHERE + body_len / 2), OBJECT_FRICTION
        )
        + _foot_spheres(r - 0.004, FOOT_SPHERE, 6, OBJECT_FRICTION)
    )
    return _sdf_model("cup", "cup", inertia, geom, {"grasp": (0, 0, 0.055), "top": (0, 0, h)})


def bottle_sdf() -> str:
    """A water bottle (0.5 kg): body cylinder and a neck; origin at the bottom centre."""
    r, hb, ht = BOTTLE_RADIUS, BOTTLE_BODY_HEIGHT, BOTTLE_HEIGHT
    neck_r, neck_len = 0.014, ht - hb
    body_m, neck_m = 0.47, 0.03
    inertia = combine(
        [
            (body_m, (0, 0, hb / 2), cylinder_inertia(body_m, r, hb)),
            (neck_m, (0, 0, hb + neck_len / 2), cylinder_inertia(neck_m, neck_r, neck_len)),
        ]
    )
    body_len = hb - FOOT_SPHERE
    geom = (
        _sdf_visual("body", "cylinder", (r, hb), (0, 0, hb / 2), (0.55, 0.8, 0.95, 0.9))
        + _sdf_visual(
            "neck",
            "cylinder",
            (neck_r, neck_len),
            (0, 0, hb + neck_len / 2),
            (0.55, 0.8, 0.95, 0.9),
        )
        + _sdf_visual(
            "cap", "cylinder", (neck_r + 0.002, 0.015), (0, 0, ht - 0.0075), (0.1, 0.3, 0.8, 1)
        )
        + _sdf_collision(
            "body", "cylinder", (r, body_len), (0, 0, FOOT_SPHERE + body_len / 2), OBJECT_FRICTION
        )
        + _sdf_collision(
            "neck", "cylinder", (neck_r, neck_len), (0, 0, hb + neck_len / 2), OBJECT_FRICTION
        )
        + _foot_spheres(r - 0.004, FOOT_SPHERE, 6, OBJECT_FRICTION)
    )
    return _sdf_model(
        "bottle", "bottle", inertia, geom, {"grasp": (0, 0, 0.10), "spout": (0, 0, ht)}
    )


def coaster_sdf() -> str:
    """A green coaster disk; origin at the bottom centre, frame ``place`` on its top."""
    r, t, m = COASTER_RADIUS, COASTER_THICKNESS, COASTER_MASS
    sphere = 0.002
    inertia = combine([(m, (0, 0, t / 2), cylinder_inertia(m, r, t))])
    disk_len = t - sphere
    geom = (
        _sdf_visual("disk", "cylinder", (r, t), (0, 0, t / 2), (0.1, 0.7, 0.2, 1))
        + _sdf_collision(
            "disk", "cylinder", (r, disk_len), (0, 0, sphere + disk_len / 2), OBJECT_FRICTION
        )
        + _foot_spheres(r - 0.006, sphere, 6, OBJECT_FRICTION)
    )
    return _sdf_model("coaster", "coaster", inertia, geom, {"place": (0, 0, t)})


def obstacle_sdf() -> str:
    """A blue ball (radius 0.06 m); origin at the ball's centre."""
    r, m = OBSTACLE_RADIUS, OBSTACLE_MASS
    inertia = combine([(m, (0, 0, 0), sphere_inertia(m, r))])
    geom = _sdf_visual("ball", "sphere", (r,), (0, 0, 0), (0.1, 0.25, 0.9, 1)) + _sdf_collision(
        "ball", "sphere", (r,), (0, 0, 0), OBJECT_FRICTION
    )
    return _sdf_model("obstacle", "obstacle", inertia, geom, {})


def table_sdf() -> str:
    """A 0.80 x 1.20 m table, top surface 0.75 m high; origin on the floor under its centre."""
    sx, sy, sz = TABLE_SIZE
    top_z = TABLE_HEIGHT - sz / 2
    leg = (0.05, 0.05, TABLE_HEIGHT - sz)
    legs = [
        (sx / 2 - 0.05, sy / 2 - 0.05),
        (sx / 2 - 0.05, -sy / 2 + 0.05),
        (-sx / 2 + 0.05, sy / 2 - 0.05),
        (-sx / 2 + 0.05, -sy / 2 + 0.05),
    ]
    parts = [(15.0, (0, 0, top_z), box_inertia(15.0, TABLE_SIZE))]
    parts += [(1.5, (x, y, leg[2] / 2), box_inertia(1.5, leg)) for x, y in legs]
    inertia = combine(parts)
    wood = (0.72, 0.55, 0.38, 1)
    geom = _sdf_visual("top", "box", TABLE_SIZE, (0, 0, top_z), wood) + _sdf_collision(
        "top", "box", TABLE_SIZE, (0, 0, top_z), TABLE_FRICTION
    )
    for k, (x, y) in enumerate(legs):
        geom += _sdf_visual(f"leg_{k}", "box", leg, (x, y, leg[2] / 2), wood)
        geom += _sdf_collision(f"leg_{k}", "box", leg, (x, y, leg[2] / 2), TABLE_FRICTION)
    return _sdf_model("table", "table", inertia, geom, {"top_center": (0, 0, TABLE_HEIGHT)})


def generated_files() -> dict[str, str]:
    """File name (relative to ``models/arm7``) -> text, for every generated model."""
    return {
        "arm7.urdf": arm7_urdf(),
        "cup.sdf": cup_sdf(),
        "bottle.sdf": bottle_sdf(),
        "coaster.sdf": coaster_sdf(),
        "obstacle.sdf": obstacle_sdf(),
        "table.sdf": table_sdf(),
    }


def main() -> None:
    """Writes every generated file next to this script."""
    for name, text in generated_files().items():
        (HERE / name).write_text(text)
        print(f"wrote {HERE / name}")


if __name__ == "__main__":
    main()
