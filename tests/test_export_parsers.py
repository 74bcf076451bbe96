"""Each exported filter file read by the parser of the tool it is for (issue 26), where that
parser is installable from the package index: OpenCV's ``cv::FileStorage`` (what VINS-Mono
/ VINS-Fusion and OpenVINS read their yaml with), GTSAM's ``PreintegrationCombinedParams``
(which takes the four covariance matrices) and the ``sensor_msgs/msg/Imu`` message type of
rosbags (its covariance arrays, serialised as a ROS 2 message). Kalibr reads its imu.yaml
with PyYAML (tested in test_export.py).

The expected numbers are rebuilt here from the known noise of test_export.py with the
conversions written out (per-sample sigma = N sqrt(f), continuous covariance = N^2)."""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import gtsam
import numpy as np
import pytest
import yaml

import imubounds as ib
from tests.test_export import RATE, TRUE, known_noise


def _worst(kind: str, i: int) -> float:
    return max(TRUE[f"{kind}_{a}"][i] for a in "xyz")


def _write(tmp_path: Path, fmt: str) -> Path:
    p = tmp_path / f"{fmt}.yaml"
    p.write_text(ib.export_noise(known_noise(), fmt), encoding="utf-8")
    return p


def test_vins_yaml_reads_in_opencv_filestorage(tmp_path: Path) -> None:
    fs = cv2.FileStorage(str(_write(tmp_path, "vins")), cv2.FILE_STORAGE_READ)
    assert fs.isOpened()
    f = math.sqrt(RATE)
    assert fs.getNode("acc_n").real() == pytest.approx(_worst("accel", 0) * f, rel=1e-6)
    assert fs.getNode("gyr_n").real() == pytest.approx(_worst("gyro", 0) * f, rel=1e-6)
    assert fs.getNode("acc_w").real() == pytest.approx(_worst("accel", 1) * f, rel=1e-6)
    assert fs.getNode("gyr_w").real() == pytest.approx(_worst("gyro", 1) * f, rel=1e-6)
    fs.release()


def test_openvins_imu_chain_reads_in_opencv_filestorage(tmp_path: Path) -> None:
    fs = cv2.FileStorage(str(_write(tmp_path, "openvins")), cv2.FILE_STORAGE_READ)
    assert fs.isOpened()
    imu = fs.getNode("imu0")
    assert imu.isMap()
    assert imu.getNode("accelerometer_noise_density").real() == pytest.approx(
        _worst("accel", 0), rel=1e-6
    )
    assert imu.getNode("gyroscope_random_walk").real() == pytest.approx(
        _worst("gyro", 1), rel=1e-6
    )
    assert imu.getNode("update_rate").real() == pytest.approx(RATE)
    t_i_b = imu.getNode("T_i_b")
    rows = [[t_i_b.at(r).at(c).real() for c in range(4)] for r in range(t_i_b.size())]
    assert np.allclose(rows, np.eye(4))
    fs.release()


def test_gtsam_takes_the_four_covariances(tmp_path: Path) -> None:
    doc = yaml.safe_load(_write(tmp_path, "gtsam").read_text(encoding="utf-8"))
    params = gtsam.PreintegrationCombinedParams.MakeSharedU(9.81)
    params.setAccelerometerCovariance(np.array(doc["accelerometerCovariance"]))
    params.setGyroscopeCovariance(np.array(doc["gyroscopeCovariance"]))
    params.setBiasAccCovariance(np.array(doc["biasAccCovariance"]))
    params.setBiasOmegaCovariance(np.array(doc["biasOmegaCovariance"]))
    want_acc = np.diag([TRUE[f"accel_{a}"][0] ** 2 for a in "xyz"])  # N^2, continuous
    want_bw = np.diag([TRUE[f"gyro_{a}"][1] ** 2 for a in "xyz"])  # K^2, continuous
    assert np.allclose(params.getAccelerometerCovariance(), want_acc, rtol=1e-6, atol=0)
    assert np.allclose(params.getBiasOmegaCovariance(), want_bw, rtol=1e-6, atol=0)


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
