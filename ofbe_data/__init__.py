"""Raw formats, manifest, gravity, convergence and the campaign simulator.

Data flows one way: raw files → typed recordings (:mod:`ofbe_data.rawio`) → labels →
windows/splits → estimators → reports.
"""

__version__ = "0.1.0"
