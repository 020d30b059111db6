#!/usr/bin/env python3
"""Golden vectors for rtls-positioning's gnss::geodetic module, from pymap3d (an independent
implementation: M. Hirsch, "pymap3d: Python 3-D coordinate conversions for geospace", JOSS 3(23),
2018; `pip install pymap3d`, tested with 3.2.0).

Prints Rust array literals to paste into crates/rtls-positioning/src/gnss/geodetic_tests.rs:
  GEODETIC_TO_ECEF: [lat_deg, lon_deg, h_m, x_m, y_m, z_m]
  ECEF_TO_GEODETIC: [x_m, y_m, z_m, lat_deg, lon_deg, h_m]
  ECEF_TO_ENU:      [lat0_deg, lon0_deg, h0_m, x_m, y_m, z_m, e_m, n_m, u_m]
  AER:              [lat0_deg, lon0_deg, h0_m, x_m, y_m, z_m, elevation_deg]
Run: python3 scripts/golden/gnss_geodetic.py

pymap3d's ecef2geodetic is approximate far from the ellipsoid (at GNSS orbit heights its
latitude is off by about 6e-5 degrees, compared with a converged Bowring iteration); the Rust
test checks those rows through the exact geodetic2ecef round trip instead.
"""
import pymap3d as pm

ELL = pm.Ellipsoid.from_name("wgs84")

GEODETIC = [
    (0.0, 0.0, 0.0),
    (48.8566, 2.3522, 35.0),          # Paris
    (-33.8688, 151.2093, 58.0),       # Sydney
    (64.1466, -21.9426, 20.0),        # Reykjavik
    (89.9999, 45.0, 100.0),           # near the north pole
    (-90.0, 0.0, 0.0),                # the south pole
    (35.0, -120.0, -400.0),           # below the ellipsoid (Death Valley-like)
    (10.0, 100.0, 20200e3),           # a GPS satellite's height
    (-45.0, -170.0, 8848.0),
]

# ECEF points (not from the list above): satellites, surface points, an aircraft
ECEF = [
    (6378137.0, 0.0, 0.0),
    (4200996.0, 172460.0, 4780102.0),
    (-2694045.0, -4293642.0, 3857878.0),
    (15600e3, 7540e3, 20140e3),
    (-14000e3, -19000e3, 11000e3),
    (1.0e3, 2.0e3, 6356752.3),
    (3e5, -4e5, -6356000.0),
]

ORIGINS = [(48.8566, 2.3522, 35.0), (-33.8688, 151.2093, 58.0), (0.0, -60.0, 0.0)]


def row(values):
    return "[" + ", ".join(repr(float(v)) for v in values) + "],"


print("const GEODETIC_TO_ECEF: [[f64; 6]; %d] = [" % len(GEODETIC))
for lat, lon, h in GEODETIC:
    print("    " + row((lat, lon, h) + pm.geodetic2ecef(lat, lon, h, ELL)))
print("];")
print("const ECEF_TO_GEODETIC: [[f64; 6]; %d] = [" % len(ECEF))
for x, y, z in ECEF:
    print("    " + row((x, y, z) + pm.ecef2geodetic(x, y, z, ELL)))
print("];")
rows = []
aer = []
for lat0, lon0, h0 in ORIGINS:
    for x, y, z in ECEF[3:5] + [pm.geodetic2ecef(lat0 + 0.01, lon0 - 0.02, h0 + 30.0, ELL)]:
        rows.append((lat0, lon0, h0, x, y, z) + pm.ecef2enu(x, y, z, lat0, lon0, h0, ELL))
        aer.append((lat0, lon0, h0, x, y, z, pm.ecef2aer(x, y, z, lat0, lon0, h0, ELL)[1]))
print("const ECEF_TO_ENU: [[f64; 9]; %d] = [" % len(rows))
for r in rows:
    print("    " + row(r))
print("];")
print("const ELEVATION: [[f64; 7]; %d] = [" % len(aer))
for r in aer:
    print("    " + row(r))
print("];")
