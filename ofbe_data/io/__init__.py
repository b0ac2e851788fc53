"""Reading and writing files: the first step of the data's journey.

The session manifest (:mod:`~ofbe_data.io.manifest`), typed recordings
(:mod:`~ofbe_data.io.recording`), the device formats (:mod:`~ofbe_data.io.formats`, one
module per format behind a registry), YAML without surprises (:mod:`~ofbe_data.io.yamlio`)
and typed configuration sections (:mod:`~ofbe_data.io.typedconfig`,
:mod:`~ofbe_data.io.pipeline_params`), local gravity (:mod:`~ofbe_data.io.gravity`), how a device file is read
(:mod:`~ofbe_data.io.device_options`), and the detection of an unknown file's layout and
units for ``ofbe-session init`` (:mod:`~ofbe_data.io.detection`, a subpackage whose public
names are in its ``__init__``, private modules behind them). It may import
:mod:`ofbe_data.core` only.
"""
