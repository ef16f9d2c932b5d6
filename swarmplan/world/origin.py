"""The world's optional ``origin``: where its point [0, 0, 0] is on the Earth (geodetic exports)."""

from __future__ import annotations

from typing import Any

from swarmplan.world.checker import Checker


def resolve_origin(c: Checker, raw: Any) -> dict[str, float] | None:
    """``origin``: the geodetic position (WGS-84 latitude and longitude in degrees, altitude in m)
    of the world's point [0, 0, 0], for geodetic exports; None when the world has none."""
    if raw is None or not c.keys(raw, "origin", ["lat", "lon", "alt"], ("lat", "lon")):
        return None
    lat = c.number(raw, "lat", "origin", None, lo=-90.0, hi=90.0)
    lon = c.number(raw, "lon", "origin", None, lo=-180.0, hi=180.0)
    alt = c.number(raw, "alt", "origin", 0.0)
    if lat is None or lon is None or alt is None:
        return None
    return {"lat": lat, "lon": lon, "alt": alt}
