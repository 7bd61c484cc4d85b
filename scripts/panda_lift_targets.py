"""Joint rows of robots/panda_lift.toml: Panda's arm pose that lifts its tool centre straight up.

The start pose is Panda's reference pose written exactly, (0, -pi/4, 0, -3pi/4,
0, pi/2, pi/4) (the model's reference holds the roundings -0.785398, -2.35619,
1.5707, 0.785398, which tilt the hand by 9.2e-5 rad), so the hand points
straight down: its rotation is diag(1, -1, -1) to round-off. The lifted pose puts the tool centre (frame
``panda_hand_tcp``) ``--lift`` metres higher with the same orientation: a
Gauss-Newton iteration with a small damping (damped least squares) on the
6-vector error ``(p - p*, log(R*^T R))`` in the world frame, started from the
start pose. Prints the start pose's numbers the scene file uses and the two
TOML rows of the arm's ``[[joint_targets]]``.

    python scripts/panda_lift_targets.py [--lift 0.10]
"""

import argparse

import numpy as np
import pinocchio as pin

import contactdiff as cd

ARM = [f"panda_joint{i}" for i in range(1, 8)]
TCP = "panda_hand_tcp"
PAD_DEPTH = 0.04525  # m: the centre of each finger's rubber pad, along its finger frame's z


def start_pose() -> np.ndarray:
    """Panda's reference arm pose written exactly (fingers as in the reference)."""
    q = cd.load_robot("panda").q_ref.copy()
    q[:7] = [0.0, -np.pi / 4, 0.0, -3 * np.pi / 4, 0.0, np.pi / 2, np.pi / 4]
    return q


def tcp_pose(model: pin.Model, data: pin.Data, q: np.ndarray) -> pin.SE3:
    """World placement of the tool centre at ``q``."""
    pin.framesForwardKinematics(model, data, q)
    return pin.SE3(data.oMf[model.getFrameId(TCP)])


def pose_error(model: pin.Model, data: pin.Data, q: np.ndarray, target: pin.SE3) -> np.ndarray:
    """``(p - p*, log3(R*^T R))``: position error (m, world) and orientation error (rad)."""
    here = tcp_pose(model, data, q)
    return np.concatenate([here.translation - target.translation, pin.log3(target.rotation.T @ here.rotation)])


def lifted_pose(lift: float, *, damping: float = 1e-8, tol: float = 1e-13, max_iter: int = 50) -> np.ndarray:
    """The configuration whose tool centre is ``lift`` m above the start's, same orientation.

    Only the seven arm joints move (the fingers keep their values). Each step solves
    ``(J^T J + damping I) dq = -J^T e`` with ``J`` the tool centre's Jacobian in the
    world-aligned frame (its angular rows mapped by the inverse right Jacobian of SO(3)).
    """
    model = cd.load_robot("panda").model
    data = model.createData()
    q = start_pose()
    start = tcp_pose(model, data, q)
    target = pin.SE3(start.rotation, start.translation + np.array([0.0, 0.0, lift]))
    fid = model.getFrameId(TCP)
    for _ in range(max_iter):
        e = pose_error(model, data, q, target)
        if np.linalg.norm(e) < tol:
            return q
        pin.computeJointJacobians(model, data, q)
        J = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)[:, :7].copy()
        here = tcp_pose(model, data, q)
        # d log3(R*^T R) = Jlog3 * (body angular velocity) = Jlog3 * R^T * (world angular velocity)
        J[3:] = pin.Jlog3(target.rotation.T @ here.rotation) @ here.rotation.T @ J[3:]
        dq = -np.linalg.solve(J.T @ J + damping * np.eye(7), J.T @ e)
        q[:7] += dq
    raise RuntimeError(f"no convergence: error {np.linalg.norm(pose_error(model, data, q, target)):.3e}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lift", type=float, default=0.10, help="m, the tool centre's rise")
    args = parser.parse_args()
    robot = cd.load_robot("panda")
    data = robot.model.createData()
    q0 = start_pose()
    q0[7:9] = 0.03  # fingers opened equally: the pads' midpoint lies on the hand's axis
    tcp = tcp_pose(robot.model, data, q0)
    pads = [
        data.oMf[robot.model.getFrameId(f"panda_{side}finger")].act(np.array([0.0, 0.0, PAD_DEPTH]))
        for side in ("left", "right")
    ]
    middle = 0.5 * (pads[0] + pads[1])
    print(f"# start: tool centre at {tcp.translation.tolist()}")
    print(
        f"# pad centres' midpoint (the box's centre) at {middle.tolist()}; "
        f"a 5 cm box's bottom face at z = {float(middle[2]) - 0.025!r}"
    )
    q1 = lifted_pose(args.lift)
    err = pose_error(robot.model, data, q1, pin.SE3(tcp.rotation, tcp.translation + [0.0, 0.0, args.lift]))
    print(f"# lifted by {args.lift} m: residual {np.linalg.norm(err[:3]):.1e} m, {np.linalg.norm(err[3:]):.1e} rad")
    print("# " + ", ".join(f'"{name}"' for name in ARM))
    for q in (q0, q1):
        print("[" + ", ".join(repr(float(x)) for x in q[:7]) + "],")


if __name__ == "__main__":
    main()
