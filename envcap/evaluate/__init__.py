"""Parallax-error evaluation against fresh captures.

``sweep`` (where: positions), ``truth`` (fresh captures filtered at exactly w), ``predict`` (the
probe set through the runtime's methods), ``metrics`` (relative RMSE, plane misfit), ``shading``
(Eq. 3 metric, materials), ``result`` (:class:`EvaluationResult`, summaries, lobe labels),
``run`` (:func:`evaluate_scene`, :func:`quick_evaluation`), ``report`` (JSON, markdown, plots).
"""
