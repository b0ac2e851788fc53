"""The model package's console scripts: each imports its command inside
:func:`ofbe_data.core.entry.run`, so that a Ctrl-C during the imports (TensorFlow's take seconds)
is one line and exit 130, not a traceback (pyproject.toml's ``[project.scripts]``).
"""

from __future__ import annotations

from ofbe_data.core.entry import console_script

train = console_script("ofbe_model.cli.train", "ofbe-train")
benchmark = console_script("ofbe_model.cli.benchmark", "ofbe-benchmark")
predict = console_script("ofbe_model.cli.predict", "ofbe-predict")
