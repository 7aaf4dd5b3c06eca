"""skytrack — from raw air-surveillance data to an identified air picture.

Packages, lowest layer first; a package imports only its own layer and the ones below it
(``tests/test_architecture.py`` checks this and the absence of file import cycles):

``core``         linear algebra, typed plot batches, track-table columns, validation
``geo``          WGS84 / ECEF / ENU, radar polar geometry, sensor descriptions
``models``       motion models (CV, CA, Singer), measurement models, plot-to-position conversion
``filters``      batched filter protocol, Kalman / EKF, psi switch, IMM, spec-000 Singer filters
``association``  gating, scoring and assignment
``tracker``      multi-target tracker (schedule, scan processing, track life cycle)
``identify``     (planned) identification of tracks against ADS-B / IFF
``sim``          scenario simulator (trajectories, rotating radars, SSR, clutter)
``analysis``     metrics against truth, evaluation, report figures
``io``           readers and writers of the FORMATS.md tables
``studies``      the studies of the papers, one module per study
``app``          pipelines shared by the command line and the demo
``cli``          the ``skytrack`` command (``service``, planned, on the same layer)
"""

__version__ = "0.1.0"
