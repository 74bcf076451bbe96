"""Each exported filter file read back by the parser of the tool it is for, node by node as
the tool reads it, and each tool's own covariance propagation fed with the exported numbers.

* OpenCV's ``cv::FileStorage`` (opencv-python-headless, a test extra) reads every node that
  OpenVINS (``ov_core/src/utils/opencv_yaml_parse.h``: ``parse_external(...)`` of the
  ``imu0`` block in ``VioManagerOptions.h``, ``StateOptions.h`` and the ROS nodes), VINS-
  Fusion (``vins_estimator/src/estimator/parameters.cpp``: ``readParameters``) and Kalibr's
  keys read, with the node types those readers expect: a double with ``>>`` or a cast
  (a real node), a text with ``>>`` (a string node: the whole line when unquoted, so no
  comment may stand beside it), a ``Eigen::Matrix3d`` as ``node[r][c]`` (a sequence of
  sequences: a flat list of nine fails OpenCV's ``isSeq()`` assertion);
* Kalibr's ``ImuParameters`` checks (PyYAML: ``rostopic`` a str, every figure > 0);
* GTSAM's ``PreintegrationCombinedParams`` takes the four covariances and its
  ``PreintegratedCombinedMeasurements`` integrates 1 s at rest;
* ``sensor_msgs/msg/Imu`` of rosbags carries the ROS covariances through a CDR round trip.

Then the covariance each consumer propagates over 1 s from the exported numbers matches the
continuous model, ``N^2 * 1 s`` for the velocity (angle) and ``K^2 * 1 s`` for the bias:
VINS's ``IntegrationBase::midPointIntegration`` (transcribed below: F, V and the 18x18
noise), OpenVINS's ``Propagator`` (``Qc = sigma^2/dt``, ``sigma_b^2*dt``), Kalibr's discrete
``sigma/sqrt(dt)`` per measurement, GTSAM's preintegration and ROS's per-message variance.

The expected numbers are rebuilt from the known noise of test_export.py."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import cv2
import gtsam
import numpy as np
import pytest
import yaml

import imubounds as ib
from imubounds.export import VINS_WHITE_FACTOR
from tests.test_export import RATE, TRUE, known_noise

DT = 1.0 / RATE


def _worst(kind: str, i: int) -> float:
    return max(TRUE[f"{kind}_{a}"][i] for a in "xyz")


def _write(tmp_path: Path, fmt: str) -> Path:
    p = tmp_path / f"{fmt}.yaml"
    p.write_text(ib.export_noise(known_noise(), fmt), encoding="utf-8")
    return p


def _open(path: Path) -> Any:
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    assert fs.isOpened(), path
    return fs


def _real(node: Any) -> float:
    """A double as ``node >> double`` reads it: a real (or int) node, not a text."""
    assert not node.empty() and (node.isReal() or node.isInt()), node.type()
    return float(node.real())


def _text(node: Any) -> str:
    assert node.isString(), node.type()
    return str(node.string())


def _matrix3d(node: Any) -> np.ndarray:
    """OpenVINS's ``parse(..., Eigen::Matrix3d&)``: ``m(r, c) = (double)node[r][c]`` for
    r < min(size, 3), c < min(node[r].size(), 3), from the identity."""
    m = np.eye(3)
    for r in range(min(node.size(), 3)):
        row = node.at(r)
        for c in range(min(row.size(), 3)):
            m[r, c] = float(row.at(c).real())
    return m


def test_openvins_reads_every_node_it_parses(tmp_path: Path) -> None:
    fs = _open(_write(tmp_path, "openvins"))
    imu = fs.getNode("imu0")
    assert imu.isMap()
    # print_and_load_noise: four doubles
    for key, kind, i in (("gyroscope_noise_density", "gyro", 0),
                         ("gyroscope_random_walk", "gyro", 1),
                         ("accelerometer_noise_density", "accel", 0),
                         ("accelerometer_random_walk", "accel", 1)):  # fmt: skip
        assert _real(imu.getNode(key)) == pytest.approx(_worst(kind, i), rel=1e-6), key
    # StateOptions: the IMU model; the ROS nodes: the topic (a text read whole)
    assert _text(imu.getNode("model")) == "kalibr"
    assert _text(imu.getNode("rostopic")) == "/imu0"
    # print_and_load_state: five Eigen::Matrix3d as nested rows
    for key, want in (("Tw", np.eye(3)), ("Ta", np.eye(3)), ("R_IMUtoACC", np.eye(3)),
                      ("R_IMUtoGYRO", np.eye(3)), ("Tg", np.zeros((3, 3)))):  # fmt: skip
        node = imu.getNode(key)
        assert node.isSeq() and node.size() == 3, key
        assert all(node.at(r).isSeq() and node.at(r).size() == 3 for r in range(3)), key
        assert np.array_equal(_matrix3d(node), want), key
    t_i_b = imu.getNode("T_i_b")
    rows = [[t_i_b.at(r).at(c).real() for c in range(4)] for r in range(t_i_b.size())]
    assert np.allclose(rows, np.eye(4))
    assert _real(imu.getNode("update_rate")) == pytest.approx(RATE)
    fs.release()


def test_the_reader_refuses_what_openvins_refused(tmp_path: Path) -> None:
    """The transcribed readers fail on the old file: a flat list of nine (OpenCV's isSeq()
    assertion, OpenVINS 'unable to parse') and a comment beside the topic."""
    old = tmp_path / "old.yaml"
    old.write_text("%YAML 1.0\n---\nimu0:\n  rostopic: /imu0  # set to your IMU topic\n"
                   "  Tw: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]\n")  # fmt: skip
    fs = _open(old)
    with pytest.raises(cv2.error, match="isSeq"):
        _matrix3d(fs.getNode("imu0").getNode("Tw"))
    assert _text(fs.getNode("imu0").getNode("rostopic")) != "/imu0"


def test_vins_fusion_reads_every_imu_node(tmp_path: Path) -> None:
    fs = _open(_write(tmp_path, "vins"))
    # readParameters: USE_IMU = fsSettings["imu"]; imu_topic >> string; four doubles; g_norm
    assert fs.getNode("imu").isInt() and int(fs.getNode("imu").real()) == 1
    assert _text(fs.getNode("imu_topic")) == "/imu0"
    s2f = math.sqrt(2.0 * RATE)
    assert _real(fs.getNode("acc_n")) == pytest.approx(_worst("accel", 0) * s2f, rel=1e-6)
    assert _real(fs.getNode("gyr_n")) == pytest.approx(_worst("gyro", 0) * s2f, rel=1e-6)
    assert _real(fs.getNode("acc_w")) == pytest.approx(_worst("accel", 1) * RATE**0.5, rel=1e-6)
    assert _real(fs.getNode("gyr_w")) == pytest.approx(_worst("gyro", 1) * RATE**0.5, rel=1e-6)
    assert 9.7 < _real(fs.getNode("g_norm")) < 9.9
    fs.release()


def test_kalibr_reads_its_keys(tmp_path: Path) -> None:
    path = _write(tmp_path, "kalibr")
    # ImuParameters (PyYAML): rostopic a str, update_rate > 0, every figure > 0
    d = yaml.safe_load(path.read_text(encoding="utf-8"))
    assert isinstance(d["rostopic"], str) and d["rostopic"] == "/imu0"
    assert d["update_rate"] > 0
    for key in ("accelerometer_noise_density", "accelerometer_random_walk",
                "gyroscope_noise_density", "gyroscope_random_walk"):  # fmt: skip
        assert isinstance(d[key], float) and d[key] > 0, key
    # the same file read by OpenCV (tools that read Kalibr's imu.yaml with FileStorage)
    fs = _open(path)
    assert _text(fs.getNode("rostopic")) == "/imu0"
    assert _real(fs.getNode("update_rate")) == pytest.approx(RATE)
    for key in ("accelerometer_noise_density", "accelerometer_random_walk",
                "gyroscope_noise_density", "gyroscope_random_walk"):  # fmt: skip
        assert _real(fs.getNode(key)) == pytest.approx(d[key], rel=1e-12), key
    fs.release()


# ----------------------------------------------- the consumers' propagation over 1 s


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def vins_covariance(acc_n: float, gyr_n: float, acc_w: float, gyr_w: float, dt: float,
                    steps: int, acc: np.ndarray, gyr: np.ndarray) -> np.ndarray:
    """VINS-Fusion's IntegrationBase::midPointIntegration, the covariance part, at constant
    ``acc``, ``gyr`` and zero bias: ``P = F P F^T + V Q V^T`` with its F (15x15), V (15x18)
    and the noise Q = diag(acc_n^2, gyr_n^2, acc_n^2, gyr_n^2, acc_w^2, gyr_w^2).
    State order O_P, O_R, O_V, O_BA, O_BG (0, 3, 6, 9, 12)."""
    Q = np.diag(np.repeat([acc_n**2, gyr_n**2, acc_n**2, gyr_n**2, acc_w**2, gyr_w**2], 3))
    P = np.zeros((15, 15))
    R0 = np.eye(3)
    I3 = np.eye(3)
    for _ in range(steps):
        w = gyr
        ang = w * dt / 2.0
        q = np.array([1.0, *ang]) / np.linalg.norm([1.0, *ang])  # delta_q * (1, w dt/2)
        x, y, z = q[1:]
        s = q[0]
        dR = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - s * z), 2 * (x * z + s * y)],
                       [2 * (x * y + s * z), 1 - 2 * (x * x + z * z), 2 * (y * z - s * x)],
                       [2 * (x * z - s * y), 2 * (y * z + s * x), 1 - 2 * (x * x + y * y)]])
        R1 = R0 @ dR
        Rw, Ra0, Ra1 = _skew(w), _skew(acc), _skew(acc)
        F = np.zeros((15, 15))
        F[0:3, 0:3] = I3
        F[0:3, 3:6] = (-0.25 * R0 @ Ra0 * dt * dt
                       - 0.25 * R1 @ Ra1 @ (I3 - Rw * dt) * dt * dt)
        F[0:3, 6:9] = I3 * dt
        F[0:3, 9:12] = -0.25 * (R0 + R1) * dt * dt
        F[0:3, 12:15] = -0.25 * R1 @ Ra1 * dt * dt * -dt
        F[3:6, 3:6] = I3 - Rw * dt
        F[3:6, 12:15] = -I3 * dt
        F[6:9, 3:6] = -0.5 * R0 @ Ra0 * dt - 0.5 * R1 @ Ra1 @ (I3 - Rw * dt) * dt
        F[6:9, 6:9] = I3
        F[6:9, 9:12] = -0.5 * (R0 + R1) * dt
        F[6:9, 12:15] = -0.5 * R1 @ Ra1 * dt * -dt
        F[9:12, 9:12] = I3
        F[12:15, 12:15] = I3
        V = np.zeros((15, 18))
        V[0:3, 0:3] = 0.25 * R0 * dt * dt
        V[0:3, 3:6] = 0.25 * -R1 @ Ra1 * dt * dt * 0.5 * dt
        V[0:3, 6:9] = 0.25 * R1 * dt * dt
        V[0:3, 9:12] = V[0:3, 3:6]
        V[3:6, 3:6] = 0.5 * I3 * dt
        V[3:6, 9:12] = 0.5 * I3 * dt
        V[6:9, 0:3] = 0.5 * R0 * dt
        V[6:9, 3:6] = 0.5 * -R1 @ Ra1 * dt * 0.5 * dt
        V[6:9, 6:9] = 0.5 * R1 * dt
        V[6:9, 9:12] = V[6:9, 3:6]
        V[9:12, 12:15] = I3 * dt
        V[12:15, 15:18] = I3 * dt
        P = F @ P @ F.T + V @ Q @ V.T
        R0 = R1
    return P


def test_vins_propagated_variance_over_one_second_is_the_continuous_model() -> None:
    """VINS's own propagation, fed with the exported acc_n, gyr_n, acc_w, gyr_w, at rest
    (gravity on z) for 1 s: the velocity variance along gravity is N^2 * 1 s within 2 % (plus
    the bias random walk's K^2 t^3 / 3, which the continuous model has too), the angle
    variance N_g^2 * 1 s, the bias variances K^2 * 1 s. Without the sqrt(2) (the per-sample
    sigma N*sqrt(f) alone) the velocity variance is half of it: the test fails on it."""
    v = yaml.safe_load(ib.export_noise(known_noise(), "vins"))
    steps = int(round(RATE))  # 1 s
    acc, gyr = np.array([0.0, 0.0, 9.81]), np.zeros(3)
    P = vins_covariance(v["acc_n"], v["gyr_n"], v["acc_w"], v["gyr_w"], DT, steps, acc, gyr)
    na, ng = _worst("accel", 0), _worst("gyro", 0)
    ka, kg = _worst("accel", 1), _worst("gyro", 1)
    assert P[8, 8] == pytest.approx(na**2 * 1.0, rel=0.02)  # velocity along gravity
    assert P[8, 8] == pytest.approx(na**2 * 1.0 + ka**2 / 3.0, rel=1e-3)  # + the bias's part
    assert np.diag(P)[3:6] == pytest.approx([ng**2 * 1.0] * 3, rel=0.02)  # angle
    assert np.diag(P)[9:12] == pytest.approx([ka**2 * 1.0] * 3, rel=0.02)  # accel bias
    assert np.diag(P)[12:15] == pytest.approx([kg**2 * 1.0] * 3, rel=0.02)  # gyro bias
    # the level axes: white noise plus the tilt error times g (1 s of angle random walk:
    # g^2 N_g^2 t^3 / 3), never less than N^2
    assert P[6, 6] == pytest.approx(na**2 + ka**2 / 3 + 9.81**2 * ng**2 / 3.0, rel=0.02)
    # the per-sample sigma without VINS's factor: half the velocity variance
    P1 = vins_covariance(v["acc_n"] / VINS_WHITE_FACTOR, v["gyr_n"] / VINS_WHITE_FACTOR,
                         v["acc_w"], v["gyr_w"], DT, steps, acc, gyr)
    assert P1[8, 8] == pytest.approx(0.5 * na**2, rel=0.02)


def test_openvins_propagated_variance_over_one_second(tmp_path: Path) -> None:
    """OpenVINS's Propagator: Qc = sigma_a^2/dt (white), sigma_ab^2*dt (bias), G's velocity
    block -R dt, bias block I; summed over 1 s at rest: N^2 * 1 s and K^2 * 1 s."""
    imu = yaml.safe_load(_write(tmp_path, "openvins").read_text())["imu0"]
    sa, sab = imu["accelerometer_noise_density"], imu["accelerometer_random_walk"]
    steps = int(round(RATE))
    var_v = sum((DT**2) * sa**2 / DT for _ in range(steps))  # G Qc G^T, velocity block
    var_b = sum(sab**2 * DT for _ in range(steps))
    assert var_v == pytest.approx(_worst("accel", 0) ** 2 * 1.0, rel=1e-9)
    assert var_b == pytest.approx(_worst("accel", 1) ** 2 * 1.0, rel=1e-9)


def test_kalibr_discrete_noise_over_one_second(tmp_path: Path) -> None:
    """Kalibr's getAccelerometerStatistics: sigma_d = sigma / sqrt(1/update_rate) per
    measurement; the velocity of f measurements of dt: f sigma_d^2 dt^2 = N^2 * 1 s."""
    d = yaml.safe_load(_write(tmp_path, "kalibr").read_text())
    sd = d["accelerometer_noise_density"] / math.sqrt(1.0 / d["update_rate"])
    assert round(RATE) * sd**2 * DT**2 == pytest.approx(_worst("accel", 0) ** 2, rel=1e-9)


def test_gtsam_takes_the_four_covariances_and_propagates_them(tmp_path: Path) -> None:
    doc = yaml.safe_load(_write(tmp_path, "gtsam").read_text(encoding="utf-8"))
    params = gtsam.PreintegrationCombinedParams.MakeSharedU(9.81)
    params.setAccelerometerCovariance(np.array(doc["accelerometerCovariance"]))
    params.setGyroscopeCovariance(np.array(doc["gyroscopeCovariance"]))
    params.setBiasAccCovariance(np.array(doc["biasAccCovariance"]))
    params.setBiasOmegaCovariance(np.array(doc["biasOmegaCovariance"]))
    params.setIntegrationCovariance(np.zeros((3, 3)))
    want_acc = np.diag([TRUE[f"accel_{a}"][0] ** 2 for a in "xyz"])  # N^2, continuous
    want_bw = np.diag([TRUE[f"gyro_{a}"][1] ** 2 for a in "xyz"])  # K^2, continuous
    assert np.allclose(params.getAccelerometerCovariance(), want_acc, rtol=1e-6, atol=0)
    assert np.allclose(params.getBiasOmegaCovariance(), want_bw, rtol=1e-6, atol=0)
    # 1 s at rest: preintMeasCov (rotation, position, velocity, bias acc, bias omega)
    pim = gtsam.PreintegratedCombinedMeasurements(params, gtsam.imuBias.ConstantBias())
    for _ in range(int(round(RATE))):
        pim.integrateMeasurement(np.array([0.0, 0.0, 9.81]), np.zeros(3), DT)
    c = np.diag(pim.preintMeasCov())
    assert c[8] == pytest.approx(TRUE["accel_z"][0] ** 2 * 1.0, rel=0.02)  # along gravity
    assert c[0:3] == pytest.approx([TRUE[f"gyro_{a}"][0] ** 2 for a in "xyz"], rel=0.02)
    assert c[9:12] == pytest.approx([TRUE[f"accel_{a}"][1] ** 2 for a in "xyz"], rel=0.02)
    assert c[12:15] == pytest.approx([TRUE[f"gyro_{a}"][1] ** 2 for a in "xyz"], rel=0.02)


def test_ros_covariances_fill_a_sensor_msgs_imu(tmp_path: Path) -> None:
    from rosbags.typesys import Stores, get_typestore

    doc = yaml.safe_load(_write(tmp_path, "ros").read_text(encoding="utf-8"))["imu"]
    store = get_typestore(Stores.ROS2_HUMBLE)
    t = store.types
    header = t["std_msgs/msg/Header"](stamp=t["builtin_interfaces/msg/Time"](sec=0, nanosec=0),
                                      frame_id="imu")  # fmt: skip
    vec = t["geometry_msgs/msg/Vector3"]
    msg = t["sensor_msgs/msg/Imu"](
        header=header,
        orientation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        orientation_covariance=np.array(doc["orientation_covariance"], dtype=np.float64),
        angular_velocity=vec(x=0.0, y=0.0, z=0.0),
        angular_velocity_covariance=np.array(doc["angular_velocity_covariance"], np.float64),
        linear_acceleration=vec(x=0.0, y=0.0, z=9.81),
        linear_acceleration_covariance=np.array(doc["linear_acceleration_covariance"],
                                                np.float64),  # fmt: skip
    )
    back = store.deserialize_cdr(store.serialize_cdr(msg, msg.__msgtype__), msg.__msgtype__)
    cov = back.angular_velocity_covariance
    assert cov.shape == (9,)
    want = [TRUE[f"gyro_{a}"][0] ** 2 * RATE for a in "xyz"]  # per-sample variance N^2 f
    assert [cov[0], cov[4], cov[8]] == pytest.approx(want, rel=1e-6)
    assert back.orientation_covariance[0] == -1.0
    # a filter integrating f messages of dt, each with that variance: N^2 * 1 s
    acc = back.linear_acceleration_covariance
    assert round(RATE) * acc[8] * DT**2 == pytest.approx(TRUE["accel_z"][0] ** 2, rel=1e-9)
