#!/usr/bin/env python3
"""Every STAC Item gissar writes validates against the published JSON schemas.

Runs `gissar simulate` (slant range) and `gissar geocode` (map geometry) on the
bundled Andorra DEM, then validates each PREFIX_stac.json with python3-jsonschema
against the STAC 1.0.0 Item schema and the schema of every extension it declares
(sar, view, projection, processing). The schemas are the published files,
copied into tests/data/stac_schemas/ (README.md there: sources and licences);
every $ref resolves to those copies, never to the network.

usage: stac_test.py GISSAR_BINARY REPOSITORY_ROOT
"""
import json
import os
import subprocess
import sys
import tempfile

import jsonschema

GISSAR, ROOT = sys.argv[1], sys.argv[2]
SCHEMAS = os.path.join(ROOT, "tests", "data", "stac_schemas")


def load_store():
    """{$id URI (with and without '#'): schema} for every bundled schema."""
    store = {}
    for base, _, names in os.walk(SCHEMAS):
        for name in names:
            if name.endswith(".json"):
                with open(os.path.join(base, name)) as f:
                    schema = json.load(f)
                uri = schema["$id"].rstrip("#")
                store[uri] = schema
                store[uri + "#"] = schema
    return store


STORE = load_store()
ITEM_SCHEMA = "https://schemas.stacspec.org/v1.0.0/item-spec/json-schema/item.json"


try:  # jsonschema >= 4.18: $ref through a `referencing` registry of the copies
    import referencing
    import referencing.jsonschema

    REGISTRY = referencing.Registry().with_resources(
        (uri, referencing.Resource.from_contents(schema, default_specification=referencing.jsonschema.DRAFT7))
        for uri, schema in STORE.items())

    def validator_for(uri):
        return jsonschema.Draft7Validator(STORE[uri], registry=REGISTRY)
except ImportError:  # Debian bookworm's python3-jsonschema 4.10: a RefResolver store
    def validator_for(uri):
        resolver = jsonschema.RefResolver(base_uri=uri, referrer=STORE[uri], store=STORE)
        return jsonschema.Draft7Validator(STORE[uri], resolver=resolver)


def validate(item):
    """Raises jsonschema.ValidationError when invalid (a $ref outside the copies fails too)."""
    for uri in [ITEM_SCHEMA] + item["stac_extensions"]:
        if uri not in STORE:
            raise AssertionError("no bundled schema for " + uri)
        validator_for(uri).validate(item)


def run(*args):
    subprocess.run([GISSAR, *args, "--quiet"], check=True)


def check_item(path, product_type):
    with open(path) as f:
        item = json.load(f)
    validate(item)
    p = item["properties"]
    for key in ("datetime", "sar:polarizations", "sar:frequency_band", "sar:instrument_mode", "sar:product_type"):
        assert key in p, key
    assert p["sar:product_type"] == product_type, p["sar:product_type"]
    assert p["sar:polarizations"] == ["VV"], p["sar:polarizations"]
    assert p["sar:frequency_band"] == "X", p["sar:frequency_band"]  # 3.1 cm = 9.67 GHz
    assert abs(p["sar:center_frequency"] - 0.299792458 / 0.031) < 1e-9
    assert abs(p["view:off_nadir"] - 50.0) < 1e-9  # depression 40 deg
    assert abs(p["view:azimuth"] - 120.0) < 1e-9  # heading 30, right-looking
    # Andorra lies within 1.4..1.8 E, 42.4..42.7 N.
    lon0, lat0, lon1, lat1 = item["bbox"]
    assert 1.3 < lon0 < lon1 < 1.9 and 42.3 < lat0 < lat1 < 42.8, item["bbox"]
    roles = set()
    for key, asset in item["assets"].items():
        href = os.path.join(os.path.dirname(path), asset["href"])
        assert os.path.exists(href), (key, href)
        roles.update(asset["roles"])
    assert {"data", "metadata"} <= roles, roles
    # The validator rejects a broken Item (so a pass above means something).
    broken = json.loads(json.dumps(item))
    broken["properties"]["sar:frequency_band"] = "Z"
    try:
        validate(broken)
    except jsonschema.ValidationError:
        pass
    else:
        raise AssertionError("an Item with sar:frequency_band Z validated")
    return item


with tempfile.TemporaryDirectory() as tmp:
    dem = os.path.join(ROOT, "data", "andorra", "andorra_srtm3_dem_filled.tif")
    sim = os.path.join(tmp, "sim")
    run("simulate", "--dem", dem, "--heading", "30", "--depression", "40", "--range-spacing", "300",
        "--azimuth-spacing", "300", "--out", sim)
    item = check_item(sim + "_stac.json", "DETECTED_SLANT_RANGE")
    assert item["properties"]["proj:code"] is None  # radar geometry: no CRS
    geo = os.path.join(tmp, "geo")
    run("geocode", "--image", sim + ".tif", "--pixel-size", "300", "--out", geo)
    item = check_item(geo + "_stac.json", "GEOCODED")
    assert item["properties"]["proj:code"] == "EPSG:32631", item["properties"]["proj:code"]
    assert len(item["properties"]["proj:transform"]) == 6
print("stac_test: every Item validates")
