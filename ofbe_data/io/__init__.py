"""Reading and writing files: the first step of the data's journey.

The session manifest (:mod:`~ofbe_data.io.manifest`), typed recordings
(:mod:`~ofbe_data.io.recording`), the device formats (:mod:`~ofbe_data.io.formats`, one
module per format behind a registry), YAML without surprises (:mod:`~ofbe_data.io.yamlio`)
and typed configuration sections (:mod:`~ofbe_data.io.typedconfig`,
:mod:`~ofbe_data.io.pipeline_params`), and local gravity (:mod:`~ofbe_data.io.gravity`). It
may import :mod:`ofbe_data.core` only.
"""
