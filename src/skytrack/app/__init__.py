"""skytrack.app — the pipelines behind the ``skytrack`` command, as a library.

``run``       :func:`~skytrack.app.run.run_tracking`: plots file -> tracker -> tracks file,
              streamed chunk by chunk, returning a :class:`~skytrack.app.run.RunSummary`
``simulate``  :func:`~skytrack.app.simulate.run_simulation` and
              :func:`~skytrack.app.simulate.write_simulation`: a scenario to plots, truth
              and sensors.json
``evaluate``  :func:`~skytrack.app.evaluate.run_evaluation`: a tracks file against truth,
              metrics written as JSON
``demo``      :func:`~skytrack.app.demo.run_demo`: simulate, track, evaluate and write the
              report folder; :func:`~skytrack.app.demo.acceptance_checks`

Layer rule: ``app`` may import every library package (core, geo, models, filters,
association, tracker, sim, analysis, io, studies) and is imported by ``cli``; it never
imports ``cli``.  Nothing here prints: long steps report through an optional ``progress``
callback ``progress(stage, completed, total)`` (see :data:`~skytrack.app.run.ProgressCallback`).
"""
