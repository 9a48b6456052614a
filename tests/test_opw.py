"""OPW industrial arms (robots/opw.py, OPWArm): fk(ik(T)) == T on every branch of every preset and of random
geometries, the joints a pose was made from among its solutions, the 8 branches distinct, singular and
out-of-reach poses as data (never NaN marked valid), the presets' fk against product-of-exponentials chains built
here from the makers' drawing dimensions, joint limits, and a batch equal to its poses solved one by one."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import sprayplan.robots.opw as opw_module
from sprayplan.errors import ConfigError, InputError
from sprayplan.robots.gantry import load_gun
from sprayplan.robots.interface import ROBOT_NAMES, OPWArm, Robot, robot_from_name
from sprayplan.robots.opw import BRANCH_LABELS, PRESETS, OPWParameters, load_opw, opw_fk, opw_ik

POS_TOL = 1e-6  # mm
ROT_TOL = 1e-9  # rad
NAMES = list(PRESETS)


def rotation_angle(r_a, r_b):
    """Angle of the rotation between two rotation stacks, accurate for small angles."""
    e = np.einsum("nji,njk->nik", r_a, r_b)
    v = np.stack([e[:, 2, 1] - e[:, 1, 2], e[:, 0, 2] - e[:, 2, 0], e[:, 1, 0] - e[:, 0, 1]], axis=1) / 2
    return np.arctan2(np.linalg.norm(v, axis=1), (np.trace(e, axis1=1, axis2=2) - 1) / 2)


def assert_same_poses(a, b):
    assert np.abs(a[:, :3, 3] - b[:, :3, 3]).max(initial=0.0) < POS_TOL
    assert rotation_angle(a[:, :3, :3], b[:, :3, :3]).max(initial=0.0) < ROT_TOL


def wide(params: OPWParameters) -> OPWParameters:
    """The same arm without joint limits (every branch of every reachable pose is valid)."""
    return dataclasses.replace(params, lower=np.full(6, -2 * math.pi), upper=np.full(6, 2 * math.pi))


def random_params(seed: int) -> OPWParameters:
    """A random OPW geometry with a sideways offset b, random signs and offsets (no limits)."""
    rng = np.random.default_rng(seed)
    lengths = dict(zip(("a1", "a2", "b", "c1", "c2", "c3", "c4"), rng.uniform(-300, 300, 7)))
    lengths["c2"] = rng.uniform(200, 900)
    lengths["c3"] = rng.uniform(200, 900)
    lengths["c4"] = rng.uniform(0, 200)
    return OPWParameters(
        name=f"random{seed}",
        **lengths,
        offsets=rng.uniform(-math.pi, math.pi, 6),
        signs=rng.choice([-1.0, 1.0], 6),
    )


def turned_distance(a, b):
    """Largest per-joint difference modulo 2 pi."""
    return np.abs((a - b + math.pi) % (2 * math.pi) - math.pi).max(axis=-1)


GEOMETRIES = [*NAMES, "random1", "random2", "random3"]


def geometry(name) -> OPWParameters:
    return random_params(int(name[-1])) if name.startswith("random") else load_opw(name)


# ----------------------------------------------------------------------------------------- round trips


@pytest.mark.parametrize("name", GEOMETRIES)
def test_fk_of_every_valid_branch_is_the_pose_and_every_branch_occurs(name):
    params = wide(geometry(name))
    rng = np.random.default_rng(11)
    q = rng.uniform(-math.pi, math.pi, (3000, 6))
    poses = opw_fk(params, q)
    sols = opw_ik(params, poses)
    assert sols.q.shape == (3000, 8, 6) and np.isfinite(sols.q).all()
    for branch in range(8):
        rows = np.flatnonzero(sols.valid[:, branch])
        assert len(rows) > 300, BRANCH_LABELS[branch]  # each branch reaches a good share of the poses
        assert_same_poses(opw_fk(params, sols.q[rows, branch]), poses[rows])
    # the joints each pose was made from are one of its solutions
    found = ((turned_distance(sols.q, q[:, None, :]) < 1e-7) & sols.valid).any(axis=1)
    assert found.all()


@pytest.mark.parametrize("name", NAMES)
def test_preset_round_trip_within_limits(name):
    params = load_opw(name)
    rng = np.random.default_rng(5)
    q = rng.uniform(params.lower, params.upper, (2000, 6))
    poses = opw_fk(params, q)
    sols = opw_ik(params, poses)
    rows, cols = np.nonzero(sols.valid)
    assert_same_poses(opw_fk(params, sols.q[rows, cols]), poses[rows])
    assert params.within_limits(sols.q[rows, cols]).all()
    # the generating joints, drawn within the limits, are found (up to whole turns of the multi-turn axes)
    found = (turned_distance(sols.q, q[:, None, :]) < 1e-7) & sols.valid
    assert found.any(axis=1).all()


@pytest.mark.parametrize("name", GEOMETRIES)
def test_the_eight_branches_are_distinct(name):
    params = wide(geometry(name))
    rng = np.random.default_rng(3)
    poses = opw_fk(params, rng.uniform(-math.pi, math.pi, (2000, 6)))
    sols = opw_ik(params, poses)
    full = sols.valid.all(axis=1)
    assert full.sum() > 100
    q = sols.q[full]
    for i in range(8):
        for j in range(i + 1, 8):
            assert (turned_distance(q[:, i], q[:, j]) > 1e-6).all(), (BRANCH_LABELS[i], BRANCH_LABELS[j])
    assert not sols.singular[full].any()


def test_branch_labels_mean_what_they_say():
    """Front shoulder: the wrist centre ahead of axis 1; elbow up: phi = theta3 + psi3 >= 0; noflip: theta5 >= 0."""
    params = wide(load_opw("abb-irb2400-10"))
    rng = np.random.default_rng(2)
    poses = opw_fk(params, rng.uniform(-math.pi, math.pi, (500, 6)))
    sols = opw_ik(params, poses)
    theta = sols.q * params.signs + params.offsets
    psi3 = math.atan2(params.a2, params.c3)
    wrist = poses[:, :3, 3] - params.c4 * poses[:, :3, 2]
    for b, label in enumerate(BRANCH_LABELS):
        ok = sols.valid[:, b]
        t = theta[ok, b]
        heading = np.stack([np.cos(t[:, 0]), np.sin(t[:, 0])], axis=1)
        ahead = np.einsum("ni,ni->n", heading, wrist[ok, :2])
        assert ((ahead >= -1e-9) if "front" in label else (ahead <= 1e-9)).all()
        phi = np.sin(t[:, 2] + psi3)
        assert ((phi >= -1e-12) if "elbow_up" in label else (phi <= 1e-12)).all()
        s5 = np.sin(t[:, 4])
        assert ((s5 >= -1e-12) if "noflip" in label else (s5 <= 1e-12)).all()


# ----------------------------------------------------------------------------------- failures as data


@pytest.mark.parametrize("name", [*NAMES, "random1"])
def test_out_of_reach_and_non_finite_poses_are_data(name):
    params = geometry(name)
    far = np.eye(4)
    far[:3, 3] = [3 * params.reach_mm + abs(params.a1) + abs(params.c1), 0.0, 0.0]
    nan = np.full((4, 4), np.nan)
    sols = opw_ik(params, np.stack([far, nan]))
    assert not sols.valid.any()
    assert np.isfinite(sols.q).all() and (sols.q == 0).all()
    assert (sols.reason[0] == "out of reach").all()
    assert (sols.reason[1] == "non-finite pose").all()


def test_inside_the_sideways_offset_is_out_of_reach():
    params = wide(random_params(1))
    assert abs(params.b) > 10
    pose = np.eye(4)
    pose[:3, 3] = [0.3 * params.b, 0.0, params.c1]
    pose[:3, 3] += params.c4 * pose[:3, 2]  # the wrist centre itself at 0.3 b from axis 1
    sols = opw_ik(params, pose)
    assert not sols.valid.any() and (sols.reason == "out of reach").all()


@pytest.mark.parametrize("name", NAMES)
def test_wrist_singular_pose_is_flagged_and_exact_or_rejected(name):
    params = load_opw(name)
    q = np.array([0.3, 0.2, -0.1, 0.7, 0.0, -0.4])  # q5 = 0: axes 4 and 6 in line
    pose = opw_fk(params, q)
    sols = opw_ik(params, pose)
    assert np.isfinite(sols.q).all()
    flagged = sols.valid & sols.singular
    assert flagged.any()
    rows, cols = np.nonzero(sols.valid)
    assert_same_poses(opw_fk(params, sols.q[rows, cols]), pose[rows])
    # the free joint is chosen as documented: q4 = 0 (or a half turn on the flipped wrist)
    q4 = sols.q[flagged][:, 3]
    assert (np.minimum(np.abs(q4), np.abs(np.abs(q4) - math.pi)) < 1e-12).all()
    strict = opw_ik(params, pose, reject_singular=True)
    assert not (strict.valid & sols.singular).any()
    assert (strict.reason[sols.singular & sols.valid] == "wrist singular").all()
    assert (strict.q[~strict.valid] == 0).all()


@pytest.mark.parametrize("name", [*NAMES, "random2"])
def test_nearly_straight_wrists_stay_exact(name):
    """Close to a singular wrist theta4 and theta6 are each ill conditioned; the pose must still come back."""
    params = wide(geometry(name))
    rng = np.random.default_rng(12)
    q = rng.uniform(-math.pi, math.pi, (400, 6))
    theta5 = np.array([1e-3, 1e-5, 1e-7, 3e-9, 1e-12, 0.0, math.pi - 1e-7, math.pi - 1e-12])
    q[:, 4] = (np.resize(theta5, 400) * rng.choice([-1, 1], 400) - params.offsets[4]) * params.signs[4]
    poses = opw_fk(params, q)
    sols = opw_ik(params, poses)
    assert sols.valid.any(axis=1).all()
    rows, cols = np.nonzero(sols.valid)
    assert_same_poses(opw_fk(params, sols.q[rows, cols]), poses[rows])


def test_shoulder_singular_pose_is_flagged_or_rejected():
    params = wide(load_opw("abb-irb2400-10"))  # b = 0: the wrist centre on axis 1 leaves q1 free
    pose = np.eye(4)
    pose[:3, 3] = [0.0, 0.0, params.c1 + 900.0]
    pose[:3, 3] += params.c4 * pose[:3, 2]
    sols = opw_ik(params, pose)
    assert sols.valid.any() and sols.singular[sols.valid].all()
    rows, cols = np.nonzero(sols.valid)
    assert_same_poses(opw_fk(params, sols.q[rows, cols]), pose[None][rows])
    strict = opw_ik(params, pose, reject_singular=True)
    assert not strict.valid.any()
    assert set(strict.reason[0]) <= {"shoulder singular", "wrist singular", "out of reach"}
    assert "shoulder singular" in set(strict.reason[0])


def test_pose_checks_raise():
    params = load_opw("abb-irb2400-10")
    with pytest.raises(InputError):
        opw_ik(params, np.eye(3))
    mirror = np.diag([1.0, 1.0, -1.0, 1.0])
    with pytest.raises(InputError):
        opw_ik(params, mirror)
    with pytest.raises(InputError):
        opw_fk(params, np.zeros(5))


# ---------------------------------------------------------------------------------------- joint limits


@pytest.mark.parametrize("name", NAMES)
def test_joint_limits_hold_and_decide_validity(name):
    """A branch is valid with the limits exactly when it is valid without them and some turn of each joint fits."""
    params = load_opw(name)
    rng = np.random.default_rng(9)
    q = rng.uniform(-math.pi, math.pi, (1500, 6))
    free = wide(params)
    poses = opw_fk(free, q)
    limited, unlimited = opw_ik(params, poses), opw_ik(free, poses)
    assert params.within_limits(limited.q[limited.valid]).all()
    k = np.arange(-3, 4) * 2 * math.pi  # turns to try
    turns = unlimited.q[..., None] + k  # (n, 8, 6, 7)
    fits = (turns >= params.lower[:, None] - 1e-9) & (turns <= params.upper[:, None] + 1e-9)
    expected = unlimited.valid & fits.any(axis=-1).all(axis=-1)
    assert (limited.valid == expected).all()
    assert limited.valid.any(axis=1).mean() > 0.2 and (~limited.valid & unlimited.valid).any()
    refused = ~limited.valid & unlimited.valid
    assert all(r.startswith("joint ") and r.endswith(" limit") for r in limited.reason[refused])
    # the joint named is one that no turn fits
    for i, b in zip(*np.nonzero(refused)):
        j = int(limited.reason[i, b].split()[1]) - 1
        assert not fits[i, b, j].any()


def test_multi_turn_axes_take_the_fewest_turns():
    params = load_opw("abb-irb2400-10")  # axis 6: +-400 deg, so q6 and q6 -+ 2 pi may both fit
    q = np.array([0.1, 0.2, 0.1, 0.3, 0.5, 0.6])
    sols = opw_ik(params, opw_fk(params, q))
    assert (np.abs(sols.q[sols.valid]) <= math.pi + 1e-12).all()


# ---------------------------------------------------------------------------- independent chains (POE)


def _axis_transform(omega, point, angle):
    """Rotation by ``angle`` about the line through ``point`` along unit ``omega``, (n, 4, 4)."""
    w = np.asarray(omega, dtype=float)
    wx = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
    a = np.asarray(angle)[:, None, None]
    rot = np.eye(3) + np.sin(a) * wx + (1 - np.cos(a)) * (wx @ wx)
    out = np.zeros((len(angle), 4, 4))
    out[:, :3, :3] = rot
    out[:, :3, 3] = (np.eye(3) - rot) @ np.asarray(point, dtype=float)
    out[:, 3, 3] = 1.0
    return out


def _chain(axes, home, q):
    """Product of exponentials: ``exp(xi1 q1) ... exp(xi6 q6) home``."""
    out = np.broadcast_to(np.eye(4), (len(q), 4, 4)).copy()
    for j, (omega, point) in enumerate(axes):
        out = out @ _axis_transform(omega, point, q[:, j])
    return out @ home


def _home(x, z):
    """The flange at the maker's zero: forearm along +x, so the flange z along +x and its x pointing down."""
    out = np.eye(4)
    out[:3, :3] = [[0, 0, 1], [0, 1, 0], [-1, 0, 0]]
    out[:3, 3] = [x, 0, z]
    return out


# Each maker's zero pose from its dimension drawing (mm): every joint axis as (direction of positive rotation,
# a point on it), and the flange pose. ABB: axis 1 about +z; axes 2, 3, 5 about +y (positive tips forward /
# down); axes 4, 6 about the forearm pointing out. KUKA: A1 about -z, A2, A3, A5 about +y, A4 and A6 about the
# forearm pointing in; its zero has the link arm horizontal.
POE = {
    # IRB 2400/10: axis 2 at 100 forward, 615 up; lower arm 705 up; forearm 135 above axis 3 and 755 long;
    # flange 85 beyond the wrist centre
    "abb-irb2400-10": (
        [
            ((0, 0, 1), (0, 0, 0)),
            ((0, 1, 0), (100, 0, 615)),
            ((0, 1, 0), (100, 0, 1320)),
            ((1, 0, 0), (0, 0, 1455)),
            ((0, 1, 0), (855, 0, 1455)),
            ((1, 0, 0), (0, 0, 1455)),
        ],
        _home(940, 1455),
    ),
    # IRB 4600-60/2.05: 175 forward, 495 up; lower arm 900; forearm 175 above axis 3 and 960 long; flange 135
    "abb-irb4600-60-205": (
        [
            ((0, 0, 1), (0, 0, 0)),
            ((0, 1, 0), (175, 0, 495)),
            ((0, 1, 0), (175, 0, 1395)),
            ((1, 0, 0), (0, 0, 1570)),
            ((0, 1, 0), (1135, 0, 1570)),
            ((1, 0, 0), (0, 0, 1570)),
        ],
        _home(1270, 1570),
    ),
    # IRB 4600-40/2.55: as the 60/2.05 with a lower arm of 1095 and a forearm of 1270
    "abb-irb4600-40-255": (
        [
            ((0, 0, 1), (0, 0, 0)),
            ((0, 1, 0), (175, 0, 495)),
            ((0, 1, 0), (175, 0, 1590)),
            ((1, 0, 0), (0, 0, 1765)),
            ((0, 1, 0), (1445, 0, 1765)),
            ((1, 0, 0), (0, 0, 1765)),
        ],
        _home(1580, 1765),
    ),
    # KR 6 R700 sixx: A2 25 forward, 400 up; link arm 315 forward (horizontal at zero); arm 35 above A3 and
    # 365 long; flange 80
    "kuka-kr6-r700-sixx": (
        [
            ((0, 0, -1), (0, 0, 0)),
            ((0, 1, 0), (25, 0, 400)),
            ((0, 1, 0), (340, 0, 400)),
            ((-1, 0, 0), (0, 0, 435)),
            ((0, 1, 0), (705, 0, 435)),
            ((-1, 0, 0), (0, 0, 435)),
        ],
        _home(785, 435),
    ),
}


@pytest.mark.parametrize("name", NAMES)
def test_preset_fk_matches_the_drawing_chain(name):
    params = load_opw(name)
    axes, home = POE[name]
    rng = np.random.default_rng(4)
    q = np.concatenate([np.zeros((1, 6)), rng.uniform(params.lower, params.upper, (500, 6))])
    got, expected = opw_fk(params, q), _chain(axes, home, q)
    assert np.abs(got - expected).max() < 1e-9


def test_known_zero_poses():
    """The flange at the maker's zero, added up from the drawing by hand."""
    assert np.allclose(opw_fk(load_opw("abb-irb2400-10"), np.zeros(6))[0, :3, 3], [100 + 755 + 85, 0, 615 + 705 + 135])
    assert np.allclose(
        opw_fk(load_opw("kuka-kr6-r700-sixx"), np.zeros(6))[0, :3, 3], [25 + 315 + 365 + 80, 0, 400 + 35]
    )
    # KUKA's home (A2 = -90, A3 = +90): link arm straight up, arm horizontal
    home = opw_fk(load_opw("kuka-kr6-r700-sixx"), np.radians([0, -90, 90, 0, 0, 0]))[0, :3, 3]
    assert np.allclose(home, [25 + 365 + 80, 0, 400 + 315 + 35])


# ------------------------------------------------------------------------------------------ batching


def test_batch_equals_one_pose_at_a_time(monkeypatch):
    params = load_opw("kuka-kr6-r700-sixx")
    rng = np.random.default_rng(8)
    poses = opw_fk(params, rng.uniform(params.lower, params.upper, (40, 6)))
    poses[5] = np.nan
    poses[7, :3, 3] = [5000.0, 0.0, 0.0]
    monkeypatch.setattr(opw_module, "_CHUNK", 7)  # several chunks, one partial
    batch = opw_ik(params, poses)
    for i in range(len(poses)):
        one = opw_ik(params, poses[i])
        assert (one.q[0] == batch.q[i]).all()
        assert (one.valid[0] == batch.valid[i]).all()
        assert (one.reason[0] == batch.reason[i]).all()
        assert (one.singular[0] == batch.singular[i]).all()


# ---------------------------------------------------------------------------------------- the Robot


@pytest.mark.parametrize("name", NAMES)
def test_opw_arm_is_a_robot_with_a_gun_and_a_base(name):
    gun = load_gun("wa101").gun2flange
    base = np.eye(4)
    base[:3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]
    base[:3, 3] = [1500.0, -200.0, 300.0]
    arm = OPWArm(load_opw(name), tcp2flange=gun, base2world=base)
    assert isinstance(arm, Robot) and arm.dof == 6 and not arm.linear_axes.any()
    assert robot_from_name(name).name == name and name in ROBOT_NAMES
    assert np.allclose(robot_from_name(name, "wa101").tcp2flange, gun)
    assert (arm.max_speed > 0).all() and arm.joint_limits.shape == (6, 2)
    q = np.random.default_rng(1).uniform(arm.joint_limits[:, 0], arm.joint_limits[:, 1], (300, 6))
    tcp2world = arm.fk(q)
    assert np.allclose(tcp2world, base @ opw_fk(arm.params, q) @ gun)
    sols = arm.ik(tcp2world)
    assert sols.branch_labels == BRANCH_LABELS and (sols.axis_error_rad == 0).all()
    rows, cols = np.nonzero(sols.valid)
    assert_same_poses(arm.fk(sols.q[rows, cols]), tcp2world[rows])
    assert arm.within_limits(sols.q[rows, cols]).all()
    assert (sols.reason[sols.valid] == "").all() and (sols.reason[~sols.valid] != "").all()


def test_bad_parameters_are_config_errors():
    good = dict(PRESETS["abb-irb2400-10"])
    for key, value, words in [
        ("c2", 0.0, "c2"),
        ("c3", math.nan, "c3"),
        ("a1", "100", "a1"),
        ("signs", [1, 1, 2, 1, 1, 1], "signs"),
        ("offsets", [0.0] * 5, "offsets"),
        ("lower", [10.0] * 6, "lower"),
        ("max_speed", [0.0] * 6, "max_speed"),
    ]:
        with pytest.raises(ConfigError, match=words):
            OPWParameters(name="bad", **{**good, key: value})
    with pytest.raises(ConfigError, match="a2 and c3"):
        OPWParameters(name="bad", **{**good, "a2": 0.0, "c3": 0.0})
    with pytest.raises(ConfigError, match="abb-irb2400-10"):
        load_opw("irb9999")
    with pytest.raises(ConfigError):
        OPWArm(PRESETS["abb-irb2400-10"])


def test_presets_carry_their_sources_and_speeds():
    for name in NAMES:
        params = load_opw(name)
        assert params.source and np.isfinite(params.max_speed).all()
        assert (params.lower < params.upper).all()


# ------------------------------------------------------------------------------- TOML files and the CLI

ARM_TOML = """kind = "opw"
name = "my-2400"
a1_mm = 100.0
a2_mm = -135.0
b_mm = 0.0
c1_mm = 615.0
c2_mm = 705.0
c3_mm = 755.0
c4_mm = 85.0
offsets_deg = [0, 0, 90, 0, 0, 0]
lower_deg = [-180, -100, -60, -200, -120, -400]
upper_deg = [180, 110, 65, 200, 120, 400]
"""


def test_toml_arm_equals_its_preset(tmp_path):
    path = tmp_path / "arm.toml"
    path.write_text(ARM_TOML)
    from_file, preset = load_opw(path), load_opw("abb-irb2400-10")
    q = np.random.default_rng(0).uniform(preset.lower, preset.upper, (50, 6))
    assert np.allclose(opw_fk(from_file, q), opw_fk(preset, q), atol=1e-9)
    assert np.allclose(from_file.lower, preset.lower) and np.isnan(from_file.max_speed).all()
    arm = robot_from_name(str(path), "wa101")
    assert isinstance(arm, OPWArm) and arm.name == "my-2400"


@pytest.mark.parametrize(
    "edit,words",
    [
        (lambda t: t.replace('kind = "opw"', 'kind = "dh"'), 'kind = "opw"'),
        (lambda t: t.replace("c2_mm = 705.0", "c2_mm = -705.0"), "c2"),
        (lambda t: t.replace("c3_mm = 755.0", 'c3_mm = "755"'), "c3_mm"),
        (lambda t: t.replace("c4_mm = 85.0\n", ""), "missing key(s) c4_mm"),
        (lambda t: t + "d7_mm = 3.0\n", "unknown key(s) d7_mm"),
        (lambda t: t.replace("[0, 0, 90, 0, 0, 0]", "[0, 0, 90]"), "offsets_deg"),
        (lambda t: t + "signs = [1, 1, 1, 1, 1, 0]\n", "signs"),
        (lambda t: t.replace("lower_deg = [-180", "lower_deg = [190"), "lower <= upper"),
        (lambda t: t + "max_speed_deg_s = [1, 1, 1, 1, 1, -1]\n", "max_speed"),
        (lambda t: t + "a1_mm = \n", "not a readable TOML"),
    ],
)
def test_bad_toml_is_one_line_exit_2_and_no_output(tmp_path, capsys, edit, words):
    from sprayplan.cli.main import main

    path = tmp_path / "arm.toml"
    path.write_text(edit(ARM_TOML))
    joints = tmp_path / "q.csv"
    joints.write_text("q1,q2,q3,q4,q5,q6\n0,0,0,0,0,0\n")
    out = tmp_path / "poses.csv"
    for argv in (["robots", str(path)], ["fk", str(joints), "-o", str(out), "--robot", str(path)]):
        capsys.readouterr()
        assert main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and str(path) in err and words in err, err
        assert not out.exists()


def test_cli_lists_describes_and_solves_opw_arms(tmp_path, capsys):
    from sprayplan.cli.main import main
    from sprayplan.io.tables import read_table

    assert main(["robots"]) == 0
    listing = capsys.readouterr().out
    assert all(name in listing for name in ROBOT_NAMES)
    assert main(["robots", "abb-irb4600-60-205"]) == 0
    text = capsys.readouterr().out
    assert "c2 900 mm" in text and "175, 175, 175, 250, 250, 360" in text and "source" in text
    assert main(["robots", "ur5"]) == 0 and "-425" in capsys.readouterr().out
    assert main(["robots", "irb9999"]) == 2 and "abb-irb2400-10" in capsys.readouterr().err

    params = load_opw("kuka-kr6-r700-sixx")
    rng = np.random.default_rng(6)
    q = np.cumsum(rng.normal(0, 0.02, (30, 6)), axis=0) + np.radians([10, -80, 100, 20, 40, -30])
    joints = tmp_path / "q.csv"
    joints.write_text("q1,q2,q3,q4,q5,q6\n" + "\n".join(",".join(f"{v:.17g}" for v in row) for row in q) + "\n")
    poses, solved = tmp_path / "poses.csv", tmp_path / "solved.csv"
    argv = ["--robot", "kuka-kr6-r700-sixx", "--pose-format", "matrix"]
    assert main(["fk", str(joints), "-o", str(poses), *argv]) == 0
    assert main(["ik", str(poses), "-o", str(solved), *argv, "--seed-joints", ",".join(map(str, q[0]))]) == 0
    back = read_table(solved, [f"q{i + 1}" for i in range(6)])
    # a smooth trajectory from its own start keeps its branch: the joints come back
    assert np.abs(back - q).max() < 1e-6
    assert main(["ik", str(poses), "-o", str(tmp_path / "all.csv"), *argv, "--all"]) == 0
    table = read_table(tmp_path / "all.csv", ["pose", "branch", *(f"q{i + 1}" for i in range(6))])
    assert np.allclose(opw_fk(params, table[:, 2:]), opw_fk(params, q[table[:, 0].astype(int) - 1]), atol=1e-5)


@pytest.mark.parametrize("name", ["ur5", "abb-irb4600-60-205"])
def test_follow_solutions_keeps_a_smooth_trajectory(name):
    from sprayplan.robots.interface import follow_solutions

    robot = robot_from_name(name)
    rng = np.random.default_rng(3)
    start = np.radians([20, 30, -20, 40, 50, 10]) if name != "ur5" else np.array([0.4, -1.3, 1.7, -1.9, -1.4, 0.6])
    q = np.cumsum(rng.normal(0, 0.01, (200, 6)), axis=0) + start
    poses = robot.fk(q)
    poses[50] = np.nan  # an unreachable waypoint is skipped, the next one follows the last reachable
    chosen, branch = follow_solutions(robot, robot.ik(poses), q[0])
    keep = np.arange(200) != 50
    assert branch[50] == -1 and (chosen[50] == 0).all() and (branch[keep] >= 0).all()
    assert np.abs(chosen[keep] - q[keep]).max() < 1e-7
