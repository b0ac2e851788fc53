"""The data package's console scripts: each imports its command inside
:func:`ofbe_data.core.entry.run`, so that a Ctrl-C during the imports (a second or two of numpy,
pandas, scipy) is one line and exit 130, not a traceback (pyproject.toml's ``[project.scripts]``).
"""

from __future__ import annotations

from ofbe_data.core.entry import console_script

simulate = console_script("ofbe_data.cli.simulate", "ofbe-simulate")
label = console_script("ofbe_data.cli.label", "ofbe-label")
convergence = console_script("ofbe_data.cli.convergence", "ofbe-convergence")
small_angle = console_script("ofbe_data.cli.small_angle", "ofbe-small-angle")
dataset = console_script("ofbe_data.cli.dataset", "ofbe-dataset")
index = console_script("ofbe_data.cli.index", "ofbe-index")
session = console_script("ofbe_data.cli.session", "ofbe-session")
autocal = console_script("ofbe_data.cli.autocal", "ofbe-autocal")
export = console_script("ofbe_data.cli.export", "ofbe-export")
