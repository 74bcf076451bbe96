"""Regenerate the small sample files in tests/data/ and the bundled demo extract.

All are cut FROM the real ADIS16405 static log (CC BY-NC-SA 4.0, University of
Calgary via SMAC-Group/imudata), found at ../shared/data/static/ beside the
repository. Run from the repository root:

    .venv/bin/python tests/data/make_samples.py

Outputs are deterministic (gzip mtime 0).
"""

from __future__ import annotations

import gzip
import io
import shutil
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
SRC = REPO.parent / "shared" / "data" / "static" / "adis16405_imu1.csv.gz"
LICENCE = SRC.parent / "LICENSE_CC-BY-NC-SA-4.0.txt"
BUNDLED = REPO / "src" / "imubounds" / "data" / "adis16405_imu1_extract.csv.gz"
N_BUNDLED = 270_000  # 45 min at 100 Hz
N_SAMPLE = 2000  # rows in the compressed samples (20 s)
N_PLAIN = 1500  # rows in the plain-text ns sample
N_EUROC = 1000  # rows in the EuRoC-style sample (long SI decimals)
START = 100_000  # sample files start at this row of the real log (t = 1000 s)
EPOCH_NS = 1_403_636_579_758_555_392  # EuRoC-like absolute start stamp
DEG = np.pi / 180.0
G0 = 9.80665


def _gzip_bytes(data: bytes) -> bytes:
    buf = io.BytesIO()
    with gzip.GzipFile(filename="", mode="wb", fileobj=buf, compresslevel=9, mtime=0) as g:
        g.write(data)
    return buf.getvalue()


def bundled_extract() -> None:
    """First 45 minutes of the real log, original text kept, gzip level 9."""
    with gzip.open(SRC, "rt", newline="") as f:
        lines = [f.readline() for _ in range(N_BUNDLED + 1)]
    BUNDLED.write_bytes(_gzip_bytes("".join(lines).encode()))
    shutil.copyfile(LICENCE, BUNDLED.parent / LICENCE.name)


def original_rows() -> tuple[str, list[str]]:
    with gzip.open(SRC, "rt", newline="") as f:
        header = f.readline()
        for _ in range(START):
            f.readline()
        rows = [f.readline() for _ in range(N_SAMPLE)]
    return header, rows


def main() -> None:
    bundled_extract()
    header, rows = original_rows()
    # plain CSV in the original units and text, time as integer ns
    vals = np.array([[float(x) for x in r.split(",")] for r in rows])
    idx = np.arange(START, START + N_SAMPLE, dtype=np.int64)
    t_ns = idx * 10_000_000
    with open(HERE / "adis_plain_ns.csv", "w", newline="") as f:
        f.write("time_ns," + header.split(",", 1)[1])
        for k, r in zip(t_ns[:N_PLAIN], rows[:N_PLAIN], strict=True):
            f.write(f"{k}," + r.split(",", 1)[1])
    # EuRoC / TUM-VI layout: SI units, absolute ns stamps, '#' header
    gyro = vals[:, 1:4] * DEG
    acc = vals[:, 4:7] * G0
    with open(HERE / "adis_euroc.csv", "w", newline="") as f:
        f.write(
            "#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],"
            "a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]\n"
        )
        for k in range(N_EUROC):
            cells = [repr(float(x)) for x in (*gyro[k], *acc[k])]
            f.write(f"{EPOCH_NS + t_ns[k] - t_ns[0]}," + ",".join(cells) + "\n")
    # Kalibr bagcreater layout, gzip: timestamp (ns), omega (rad/s), alpha (m/s^2)
    text = io.StringIO()
    text.write("timestamp,omega_x,omega_y,omega_z,alpha_x,alpha_y,alpha_z\n")
    for k in range(N_SAMPLE):
        cells = [repr(float(x)) for x in (*gyro[k], *acc[k])]
        text.write(f"{t_ns[k]}," + ",".join(cells) + "\n")
    (HERE / "adis_kalibr.csv.gz").write_bytes(_gzip_bytes(text.getvalue().encode()))
    # Parquet with the original columns and units
    names = header.strip().split(",")
    table = pa.table({n: vals[:, i] for i, n in enumerate(names)})
    pq.write_table(table, HERE / "adis.parquet", compression="zstd")
    # whitespace-separated TXT with a comment preamble, time in ms
    with open(HERE / "adis_spaces.txt", "w", newline="") as f:
        f.write("# ADIS16405 extract, space separated\n# units: deg/s and g\n")
        f.write("t_ms gyro_x_dps gyro_y_dps gyro_z_dps accel_x_g accel_y_g accel_z_g\n")
        for k, r in zip(t_ns[:500], rows[:500], strict=True):
            f.write(f"{k // 1_000_000} " + " ".join(r.strip().split(",")[1:]) + "\n")


if __name__ == "__main__":
    main()
