"""What ``ofbe-export FORMAT --help`` shows of the calibration formats: their options' defaults
and choices, and the names of the files they add.

Apart from the conversions (:mod:`~ofbe_data.calibration.formats`) and what each format does
(:mod:`~ofbe_data.calibration.handlers`), which import NumPy, pandas and the readers, so that
the parser of ``ofbe-export`` is built from light modules alone
(:mod:`~ofbe_data.calibration.exports`). Those modules import these names from here.
"""

from __future__ import annotations

DEFAULT_FRAME_ID = "imu_link"
"""ROS ``frame_id`` when none is given (REP 145's IMU frame)."""
DEFAULT_ROSTOPIC = "/imu0"
"""Kalibr ``rostopic`` when none is given."""
ROS_NODE = "/**"
"""Node name of the ROS 2 parameter file: ``/**`` gives the parameters to every node that loads
the file (``--ros-args --params-file``); ``ofbe-export ros --ros-node NAME`` names one."""
GGIR_CONVENTIONS = ("unit-sphere", "local")
"""``--g-convention`` of the GGIR export: GGIR's own (calibrated readings at rest on the sphere of
radius 1 g, as its auto-calibration makes them) or ofbe's (radius g_local / g0)."""
GGIR_DATA = "ggir-data"
"""Folder of ``--out`` that ``ggir --ggir-data`` writes the rebuilt data files into, under GGIR's names."""
GGIR_DATA_README = "ggir-data.README.txt"
"""Notes beside ``ggir-data/``: the layout of the rebuilt files and the ``rmc.*`` settings to pass."""
