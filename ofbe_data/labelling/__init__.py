"""From recordings to labels: synchronisation, stationarity, orientation, the pose and campaign fits.

Tap synchronisation (:mod:`~ofbe_data.labelling.sync`), static detection
(:mod:`~ofbe_data.labelling.stationarity`), Rodrigues' rotation and the nearest-axis rule
(:mod:`~ofbe_data.labelling.orientation`), the multi-position fit
(:mod:`~ofbe_data.labelling.multiposition._fit`), the campaign fit
(:mod:`~ofbe_data.labelling.campaign_fit`), convergence and Allan deviation
(:mod:`~ofbe_data.labelling.convergence`, :mod:`~ofbe_data.labelling.allan`), the small-angle
leak (:mod:`~ofbe_data.labelling.smallangle`), per-session labelling
(:mod:`~ofbe_data.labelling.labels`), the label files (:mod:`~ofbe_data.labelling.store`) and
``ofbe-label`` (:mod:`~ofbe_data.cli.label`). It may import :mod:`ofbe_data.core` and
:mod:`ofbe_data.io`; never the simulator (labels must come from the files alone).
"""
