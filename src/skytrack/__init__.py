"""skytrack — from raw air-surveillance data to an identified air picture.

Packages (lower ones never import higher ones, ``cli`` sits on top):

``geo``          WGS84 / ECEF / ENU, radar polar geometry, sensor descriptions
``models``       motion models (CV, CA, Singer) and measurement models (polar, Cartesian)
``filters``      batched extended Kalman filter, spec-000 Singer filters
``association``  gating and global-nearest-neighbour assignment
``tracker``      multi-target tracker (track life cycle, scan processing)
``analysis``     metrics against truth, the papers' studies
``sim``          scenario simulator (trajectories, rotating radars, SSR, clutter)
``io``           readers and writers of the FORMATS.md tables
``cli``          the ``skytrack`` command
"""

__version__ = "0.1.0"
