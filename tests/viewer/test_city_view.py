"""``envcap view`` on a city directory (``city.json``, one shard per street) and ``envcap export web``
of one: every street of the city is on the map, the view starts in shard 0 and loads another
street's shard when the camera goes there (its lookups then equal the numpy twin on the city's
merged probe set), a shard without its face atlas is refused with the command that makes it, and
that command's export makes the atlas byte-identical to the bake's."""

import json
import shutil
import subprocess
import sys
import urllib.request

import numpy as np
import pytest
from viewer_pages import open_page

from envcap.probeset.store import read_city_probe_set
from envcap.runtime.chains import ProbeChains
from envcap.runtime.sampling import sample_street
from envcap.runtime.street import RuntimeStreet
from envcap.viewer import serve
from envcap.viewer.city_site import CitySite
from envcap.viewer.site_dir import open_site

STREET_GREY = (85, 85, 85)   # the map's street fill, #555


@pytest.fixture(scope="module")
def city_dir(gl_ctx, tmp_path_factory):
    """The bundled crossing as a city: two streets, one shard each, 8^2 faces, with face atlases (~1 s)."""
    from envcap.city.bake import bake_city
    from envcap.city.plan import BakeSettings

    out = tmp_path_factory.mktemp("city_view") / "crossing"
    bake_city("crossing", out, BakeSettings(resolution=8, spacing=100.0, writers=("ktx2", "webgl2")), budget_mb=0,
              ctx=gl_ctx)
    return out


@pytest.fixture(scope="module")
def city_page(chromium, city_dir):
    server, _ = serve(open_site(city_dir))
    try:
        yield server, open_page(chromium, server.url)
    finally:
        server.shutdown()
        server.server_close()


def map_pixel(b, x, z):
    return b.evaluate(f"(() => {{ const [u, v] = window.envcap.mapPoint({x}, {z});"
                      " return Array.from(document.getElementById('map').getContext('2d')"
                      ".getImageData(Math.round(u), Math.round(v), 1, 1).data.slice(0, 3)); })()")


def test_city_config_lists_every_street_and_serves_each_shard(city_page, city_dir):
    server, b = city_page
    site = server.site
    assert isinstance(site, CitySite)
    with urllib.request.urlopen(server.url + "api/config.json", timeout=10) as r:
        cfg = json.load(r)
    assert [(s["name"], s["shard"]) for s in cfg["city"]["streets"]] == [("east_west", 0), ("north_south", 1)]
    assert [s["name"] for s in cfg["streets"]] == ["east_west"]   # the view starts in shard 0
    with urllib.request.urlopen(server.url + cfg["city"]["shards"][1]["config"], timeout=10) as r:
        shard1 = json.load(r)
    assert [s["name"] for s in shard1["streets"]] == ["north_south"]
    with urllib.request.urlopen(server.url + shard1["files"]["atlas"], timeout=10) as r:
        assert r.read() == (city_dir / site.index.shards[1].path / "probes_atlas.ktx2").read_bytes()
    status = b.evaluate("document.getElementById('status').textContent")
    assert "a city of 2 streets in 2 shards" in status, status
    assert b.errors == []


def test_map_shows_every_street_and_going_there_loads_its_shard(city_page, city_dir):
    server, b = city_page
    # both streets on the map (off their probe lines and the crossing), before shard 1 is loaded
    assert map_pixel(b, -120.0, 4.0) == list(STREET_GREY)
    assert map_pixel(b, 4.0, 120.0) == list(STREET_GREY)
    assert map_pixel(b, 60.0, 60.0) != list(STREET_GREY)   # between the streets: not a street
    assert b.evaluate("window.envcap.viewer.shard") == 0
    # go to the north-south street (a map click does the same) and wait for its shard
    b.evaluate("(() => { const v = window.envcap.viewer; v.cam.pos = [0.0, 2.0, 100.0]; v.render(); return true; })()")
    assert b.evaluate("window.envcap.settled()") == 1
    where = b.evaluate("document.getElementById('where').textContent")
    assert "street north_south (shard 2 of 2)" in where, where
    # the loaded shard's lookups are the city's: numpy twin on the merged probe set, street 1
    ps = read_city_probe_set(city_dir, distance=False)
    st = ps.manifest.streets[1]
    rng = np.random.default_rng(5)
    n = 300
    x = np.float32(np.c_[rng.uniform(-5, 5, n), rng.uniform(0.3, 10, n), rng.uniform(-140, 140, n)]).astype(np.float64)
    d = rng.normal(size=(n, 3))
    d = np.float32(d / np.linalg.norm(d, axis=1, keepdims=True)).astype(np.float64)
    w = np.float32(np.exp(rng.uniform(0, np.log(1e4), n))).astype(np.float64)
    args = json.dumps(["planes_mip", 0, x.ravel().tolist(), d.ravel().tolist(), w.tolist()])
    got = np.array(b.evaluate(f"window.envcap.lookups(...JSON.parse({json.dumps(args)}))"), np.float64).reshape(-1, 3)
    ref = sample_street(ProbeChains(ps.levels, ps.manifest.lobes.powers), ps.sky_levels, RuntimeStreet.from_manifest(st),
                        x, d, w, "planes_mip")
    err = np.abs(got - ref).max() / np.abs(ref).max()
    assert err < 1e-4, f"shard 1's planes_mip lookups: max error {err:.2e} of the largest value"
    # and back: shard 0 again
    b.evaluate("(() => { const v = window.envcap.viewer; v.cam.pos = [-100.0, 2.0, 0.0]; v.render(); return true; })()")
    assert b.evaluate("window.envcap.settled()") == 0
    assert b.errors == []


def test_city_without_an_atlas_names_the_command_and_the_export_makes_it(city_dir, tmp_path):
    plain = tmp_path / "crossing"
    shutil.copytree(city_dir, plain)
    site = CitySite.open(city_dir)
    (plain / site.index.shards[1].path / "probes_atlas.ktx2").unlink()
    with pytest.raises(ValueError) as e:
        open_site(plain)
    msg = str(e.value)
    assert "no probes_atlas.ktx2" in msg and f"envcap export web {plain} --out {plain}-web" in msg, msg
    # the command it names, run as the user would
    proc = subprocess.run([sys.executable, "-m", "envcap", "export", "web", str(plain), "--out", f"{plain}-web"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    web = open_site(f"{plain}-web")
    assert isinstance(web, CitySite)
    for sh in site.index.shards:
        made = (tmp_path / "crossing-web" / "set" / sh.path / "probes_atlas.ktx2").read_bytes()
        assert made == (city_dir / sh.path / "probes_atlas.ktx2").read_bytes()
    assert json.loads((tmp_path / "crossing-web" / "api" / "config.json").read_text())["city"]["shards"][1]["config"] \
        == "api/shards/1.json"
    assert (tmp_path / "crossing-web" / "api" / "shards" / "1.json").is_file()
