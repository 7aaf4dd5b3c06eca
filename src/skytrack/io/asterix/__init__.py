"""ASTERIX codec for radar plots (issue 11 item 1-2): CAT048 target reports and CAT034 service messages.

:func:`encode_asterix` writes plots (I048/010, 140, 020, 040, 070, 090, 220) and north
markers / sector crossings (I034/000, 010, 030, 020) with libasterix; :func:`decode_asterix`
reads the same items back with numpy (a compiled scan finds the records), in the plots
layout of docs/formats.md, with problems counted by byte offset (:class:`DecodeProblems`)
or raised (:class:`AsterixDecodeError`) in strict mode.
"""

from skytrack.io.asterix.decode import DecodedAsterix, decode_asterix
from skytrack.io.asterix.encode import encode_asterix
from skytrack.io.asterix.problems import AsterixDecodeError, AsterixProblem, DecodeProblems

__all__ = ["AsterixDecodeError", "AsterixProblem", "DecodeProblems", "DecodedAsterix", "decode_asterix",
           "encode_asterix"]
