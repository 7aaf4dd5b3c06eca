"""Resolutions of the ASTERIX items skytrack reads and writes (issue 11 item 1-2).

I048/040 RHO 1/256 NM and THETA 360/2^16 deg; I048/140 and I034/030 time of day 1/128 s;
I048/090 flight level 1/4 FL (25 ft); I034/020 sector azimuth 360/2^8 deg.  The plots
columns are SI (metres, seconds) and degrees; 1 NM = 1852 m.
"""

from __future__ import annotations

NAUTICAL_MILE_M = 1852.0
RHO_LSB_M = NAUTICAL_MILE_M / 256.0
THETA_LSB_DEG = 360.0 / 65536.0
TIME_LSB_S = 1.0 / 128.0
FLIGHT_LEVEL_LSB_FT = 25.0
SECTOR_LSB_DEG = 360.0 / 256.0
SECONDS_PER_DAY = 86400.0

#: I048/020 TYP: what detected the target
TYP_NO_DETECTION = 0
TYP_PSR = 1
TYP_SSR = 2
TYP_SSR_PSR = 3
TYP_MODE_S_ROLL_CALL = 5
TYP_MODE_S_ROLL_CALL_PSR = 7

#: I034/000 message types
NORTH_MARKER = 1
SECTOR_CROSSING = 2
