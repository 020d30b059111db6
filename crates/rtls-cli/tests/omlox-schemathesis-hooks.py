"""schemathesis hooks of the omlox conformance run (omlox_schemathesis.rs sets SCHEMATHESIS_HOOKS).

One hook, `filter_failure`: it drops a "Schema-valid request rejected" failure (ST202, the
positive_data_acceptance check) only when the refusal is one of the exceptions below — a
request the omlox schema permits but the spec's text forbids or the hub cannot honour — and
only when the request really is such a request: the answer is an omlox Error (400) naming the
field at fault, and the request's own value of that field shows the reason. Every other
refusal of a schema-valid request still fails the run, and every other check still sees these
requests. The spec sentence behind each exception is in omlox-schemathesis.toml, by the
exception's name.
"""

import re
from datetime import datetime, timedelta, timezone

import schemathesis

# the example site's own zone (uuid_for("zone", its name)), read-only: it is the site file's
SITE_ZONE = "b17a72f9-2ded-5748-b6ae-001a7bd0dc3a"
# CRSs the hub projects (crate::omlox::crs::Crs)
SUPPORTED_CRS = {"local", "epsg:4326", "wgs84"}
# the example site's pipeline.max_record_age_s and max_record_lead_s are at most this
RECORD_WINDOW = timedelta(days=1)
# no site spans the Earth's radius (m)
EARTH_RADIUS_M = 6.371e6


def _error(response):
    """The omlox Error of a 400, or None."""
    if response.status_code != 400:
        return None
    try:
        body = response.json()
    except ValueError:
        return None
    if isinstance(body, dict) and {"type", "code", "message"} <= body.keys():
        return body
    return None


def _at(document, field):
    """The value at an Error's `field` path (`[0].crs`, `region.coordinates[0][2]`), or None."""
    for token in re.findall(r"\[\d+\]|[^.\[\]]+", field):
        if token.startswith("["):
            index = int(token[1:-1])
            if not isinstance(document, list) or index >= len(document):
                return None
            document = document[index]
        else:
            if not isinstance(document, dict) or token not in document:
                return None
            document = document[token]
    return document


def _value(case, field):
    """The request's value of `field`: a query parameter, else a path into the body (a single
    Location or Proximity body is the hub's item `[0]`)."""
    if case.query and field in case.query:
        return case.query[field]
    if isinstance(case.body, dict) and field.startswith("[0]."):
        field = field[len("[0].") :]
    return _at(case.body, field)


def _is_degrees(position):
    return (
        isinstance(position, list)
        and 2 <= len(position) <= 3
        and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in position)
        and -180 <= position[0] <= 180
        and -90 <= position[1] <= 90
    )


def unsupported_crs(case, error):
    field = error.get("field", "")
    if not re.fullmatch(r"(\[\d+\]\.)?crs", field):
        return False
    value = _value(case, field)
    return not (isinstance(value, str) and value.lower() in SUPPORTED_CRS)


def coordinates_not_degrees(case, error):
    field = error.get("field", "")
    match = re.match(r"(\[\d+\])?\.?(region|position)\.coordinates", field)
    if not match:
        return False
    # the object that names the CRS: the body, or a Location of an array body
    owner = _at(case.body, match.group(1)) if match.group(1) and isinstance(case.body, list) else case.body
    crs = str(owner.get("crs")).lower() if isinstance(owner, dict) and "crs" in owner else None
    if case.operation.path.startswith("/zones"):
        in_degrees = True  # a zone's position is EPSG:4326
    elif match.group(2) == "region":
        in_degrees = crs in (None, "epsg:4326", "wgs84")  # a fence's default is EPSG:4326
    else:
        in_degrees = crs in ("epsg:4326", "wgs84")  # a location's default is local
    return in_degrees and not _is_degrees(_value(case, field))


def local_coordinates_off_the_globe(case, error):
    field = error.get("field", "")
    if not field.startswith("region.coordinates") or "no place on the globe" not in error["message"]:
        return False
    position = _value(case, field)
    # a Point region's centre may be named by `region.coordinates` itself
    numbers = position if isinstance(position, list) else []
    return any(isinstance(v, (int, float)) and abs(v) >= EARTH_RADIUS_M for v in numbers)


def geometry_without_coordinates(case, error):
    match = re.fullmatch(r"((\[\d+\]\.)?(position|region|geometry))(\.type|\.coordinates)?", error.get("field", ""))
    if not match:
        return False
    geometry = _value(case, match.group(1))
    return isinstance(geometry, dict) and not {"type", "coordinates"} <= geometry.keys()


def unknown_proximity_source(case, error):
    field = error.get("field", "")
    if not case.operation.path.endswith(("/proximities", "/proximity")) or not re.fullmatch(r"(\[\d+\]\.)?source", field):
        return False
    return error["message"].startswith("no zone has the id") or _value(case, field) == ""


def negative_magnitude(case, error):
    field = error.get("field", "")
    if not re.fullmatch(r"(\[\d+\]\.)?(accuracy|speed)", field):
        return False
    value = _value(case, field)
    return isinstance(value, (int, float)) and value < 0


def point_fence_without_radius(case, error):
    if not case.operation.path.startswith("/fences") or error.get("field") != "radius":
        return False
    body = case.body if isinstance(case.body, dict) else {}
    region = body.get("region") if isinstance(body.get("region"), dict) else {}
    radius = body.get("radius")
    return region.get("type") == "Point" and not (isinstance(radius, (int, float)) and radius > 0)


def proximity_zone_without_position(case, error):
    if not case.operation.path.startswith("/zones") or error.get("field") != "position":
        return False
    body = case.body if isinstance(case.body, dict) else {}
    position = body.get("position")
    return (
        body.get("type") in ("rfid", "ibeacon")
        and body.get("incomplete_configuration") is not True
        and not (isinstance(position, dict) and {"type", "coordinates"} <= position.keys())
    )


def ground_control_point_not_a_pair(case, error):
    field = error.get("field", "")
    if not re.fullmatch(r"ground_control_points\[\d+\]", field):
        return False
    point = _value(case, field)
    return not (isinstance(point, list) and len(point) == 2)


def elevation_ref_not_floor_or_wgs84(case, error):
    field = error.get("field", "")
    return bool(re.fullmatch(r"(\[\d+\]\.)?elevation_ref", field)) and _value(case, field) not in ("floor", "wgs84")


def ring_without_three_corners(case, error):
    if not case.operation.path.startswith("/fences") or error.get("field") not in (
        "region",
        "region.coordinates",
        "region.coordinates[0]",
    ):
        return False
    region = case.body.get("region") if isinstance(case.body, dict) else None
    rings = region.get("coordinates") if isinstance(region, dict) else None
    ring = rings[0] if isinstance(rings, list) and rings else []
    corners = {tuple(p[:2]) for p in ring if isinstance(p, list) and len(p) >= 2}
    return region.get("type") == "Polygon" and len(corners) < 3


def empty_identifier(case, error):
    field = error.get("field", "")
    if not re.fullmatch(r"(\[\d+\]\.)?(source|provider_id|id)", field) or error["message"] != "must not be empty":
        return False
    value = _value(case, field)
    return isinstance(value, str) and not value.strip()


def proximity_zone_without_radius(case, error):
    if not case.operation.path.startswith("/zones") or error.get("field") != "radius":
        return False
    body = case.body if isinstance(case.body, dict) else {}
    radius = body.get("radius")
    return body.get("type") in ("rfid", "ibeacon") and not (isinstance(radius, (int, float)) and radius > 0)


def zone_without_local_frame(case, error):
    if case.operation.path == "/zones/{zone_id}/transform":
        return error.get("field") == "ground_control_points" and "needs three ground control points" in error["message"]
    return (
        error.get("field") == "zone_id"
        and bool(case.query)
        and "zone_id" in case.query
        and ("has no local frame" in error["message"] or "ground control points" in error["message"])
    )


def fence_zone_without_local_frame(case, error):
    if not case.operation.path.startswith("/fences") or error.get("field") != "zone_id":
        return False
    body = case.body if isinstance(case.body, dict) else {}
    crs = body.get("crs")
    return (
        isinstance(crs, str)
        and crs.lower() == "local"
        and body.get("zone_id") != SITE_ZONE
        and any(reason in error["message"] for reason in ("no zone has the id", "no local frame", "ground control points"))
    )


def proximity_zone_with_ground_control_points(case, error):
    if not case.operation.path.startswith("/zones") or error.get("field") != "ground_control_points":
        return False
    body = case.body if isinstance(case.body, dict) else {}
    return body.get("type") in ("rfid", "ibeacon") and "ground_control_points" in body


def region_not_simple(case, error):
    return (
        case.operation.path.startswith("/fences")
        and error.get("field") == "region"
        and "the polygon must be simple" in error["message"]
    )


def rule_does_not_parse(case, error):
    return bool(re.fullmatch(r"locating_rules\[\d+\]\.expression", error.get("field", ""))) and (
        "does not parse" in error["message"]
    )


def id_in_use(case, error):
    return (
        case.method.upper() == "POST"
        and case.operation.path in ("/providers", "/fences")
        and error.get("field") == "id"
        and "exists" in error["message"]
    )


def id_contradicts_path(case, error):
    field = error.get("field")
    if case.method.upper() != "PUT" or field not in ("id", "provider_id") or not isinstance(case.body, dict):
        return False
    path_ids = [str(v) for v in (case.path_parameters or {}).values()]
    return "does not match the path's" in error["message"] and str(case.body.get(field)) not in path_ids


def zone_without_frame(case, error):
    if case.operation.path not in ("/zones", "/zones/{zone_id}") or error.get("field") != "ground_control_points":
        return False
    body = case.body if isinstance(case.body, dict) else {}
    points = body.get("ground_control_points")
    if isinstance(points, list) and len(points) % 2 == 1:
        # an unpaired position: no [longitude, latitude] / [x, y] mapping
        return "even number" in error["message"]
    return body.get("incomplete_configuration") is not True and (not isinstance(points, list) or len(points) < 6)


def outside_record_window(case, error):
    field = error.get("field", "")
    if not re.fullmatch(r"(\[\d+\]\.)?timestamp_(generated|sent)", field) or "pipeline.max_record_" not in error["message"]:
        return False
    stamp = _value(case, field)
    try:
        stamp = datetime.fromisoformat(stamp.replace("Z", "+00:00"))
    except (AttributeError, ValueError):
        return False
    return abs(datetime.now(timezone.utc) - stamp) > RECORD_WINDOW


def site_zone_read_only(case, error):
    return (
        case.operation.path == "/zones/{zone_id}"
        and case.method.upper() in ("PUT", "DELETE")
        and error.get("field") == "zone_id"
        and (case.path_parameters or {}).get("zone_id") == SITE_ZONE
    )


def zone_without_area(case, error):
    return case.operation.path == "/zones/{zone_id}/createfence" and error.get("field") in (
        "ground_control_points",
        "radius",
        "position",
    )


EXCEPTIONS = [
    unsupported_crs,
    coordinates_not_degrees,
    local_coordinates_off_the_globe,
    geometry_without_coordinates,
    unknown_proximity_source,
    negative_magnitude,
    point_fence_without_radius,
    proximity_zone_without_position,
    rule_does_not_parse,
    proximity_zone_with_ground_control_points,
    region_not_simple,
    empty_identifier,
    proximity_zone_without_radius,
    zone_without_local_frame,
    fence_zone_without_local_frame,
    ground_control_point_not_a_pair,
    elevation_ref_not_floor_or_wgs84,
    ring_without_three_corners,
    id_in_use,
    id_contradicts_path,
    zone_without_frame,
    outside_record_window,
    site_zone_read_only,
    zone_without_area,
]


@schemathesis.hook
def filter_failure(context, failure, case, response):
    """Keeps every failure but an ST202 that one of EXCEPTIONS explains."""
    if getattr(failure, "code", None) != "ST202":
        return True
    error = _error(response)
    return error is None or not any(exception(case, error) for exception in EXCEPTIONS)
