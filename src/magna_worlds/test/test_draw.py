"""World pictures: a real PNG with something in it, written atomically, never over a file without --force."""
import json

import numpy as np
import pytest
from matplotlib.image import imread
from mpl_toolkits.mplot3d import Axes3D

from magna_master import cli
from magna_worlds import draw
from magna_worlds.generate import resolve_world
from magna_worlds.loader import world_from_data
from magna_worlds.shapes import contains, half_extents, parse_shape
from tests.support import CORPUS

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def magna(capsys, *argv):
    status = cli.main([str(a) for a in argv])
    out = capsys.readouterr()
    return status, out.out, out.err


def assert_png_with_content(path):
    """A PNG with more than a few colours in it; returns its RGB pixels (H, W, 3) as int."""
    data = path.read_bytes()
    assert data[:8] == PNG_SIGNATURE
    image = (imread(path)[..., :3] * 255).round().astype(np.int32)
    colours = len(np.unique(image[..., 0] << 16 | image[..., 1] << 8 | image[..., 2]))
    assert colours > 50, f"{path} looks blank ({colours} colours)"
    return image


def every_shape_world(random_poses=20):
    """All five shapes, turned frames, every pose-set type and obstacles of every shape."""
    def geometry(name, shape, dims, origin, color, alpha, sets):
        return {"name": name, "prefix": name[:2], "shape": shape, "id": 0, "origin": origin, "dimensions": dims,
                "color": color, "alpha": alpha, "poses_sets": sets}

    return {"scenario": {"world_boundaries": [[-900, 900], [-900, 900], [-900, 900]], "volumes": [{
        "name": "Field", "prefix": "F", "origin": [[100, 0, 0], [0, 0, 0.3]], "permits": "geofence",
        "geometries": [
            geometry("Crop", "prism", [6.0, [[-20, -10, 0], [20, -12, 0], [25, 8, 0], [0, 2, 0], [-18, 6, 0]]],
                     [[0, 0, 0], [0, 0, 0]], [0, 160, 0], 0.2,
                     [{"type": "zigzag", "use": "poses", "height": 4, "spacing": [0, 4], "margins": [1, 1]}]),
            geometry("Ball", "sphere", [10, 10, 10], [[0, 30, 8], [0, 0, 0]], [255, 0, 0], 0.3,
                     [{"type": "random", "use": "poses", "quantity": random_poses}]),
            geometry("Ring", "torus", [8, 12, 4], [[30, 30, 5], [0.5, 0, 0]], [255, 255, 255], 0.0,
                     [{"type": "matrix", "use": "poses", "dimensions": [12, 1, 1]},
                      {"type": "random", "use": "obstacles", "quantity": 4,
                       "obstacles_shape": ["cube", "sphere", "torus", "cylinder"],
                       "obstacles_dimensions": [[0.5, 1], [0.5, 1], [0.3, 0.5]]}]),
            geometry("Can", "cylinder", [8, 8, 10], [[-30, 30, 5], [0, 0.2, 0]], [200, 200, 0], 1.0,
                     [{"type": "matrix", "use": "poses", "matrix_type": "distance", "dimensions": [2, 2, 3]},
                      {"type": "coordinates", "use": "poses", "coordinates": [[[0, 0, 0], [0, 0, 0]]]},
                      {"type": "random", "use": "obstacles", "quantity": 2, "obstacles_shape": "prism",
                       "obstacles_dimensions": [1, [[0, 0, 0], [1, 0, 0], [0, 1, 0]]]}]),
            geometry("Box", "cube", [4, 4, 2], [[0, -30, 1], [0, 0, 0]], [0, 0, 0], 0.5, []),
        ]}]}}


def resolved(data, seed=0):
    return resolve_world(world_from_data(data, "every_shape.json"), seed)


def test_every_shape_and_pose_set_draws(tmp_path):
    out = draw.draw_world(resolved(every_shape_world()), tmp_path / "all.png")
    assert out == tmp_path / "all.png"
    rgb = assert_png_with_content(out)
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    assert np.count_nonzero((g > r + 30) & (g > b + 30)) > 2000  # the green field (prism), translucent
    assert np.count_nonzero((r > 100) & (g > 100) & (b < r - 50) & (abs(r - g) < 30)) > 1000  # the yellow can
    assert np.count_nonzero((r > b + 40) & (r > g + 40)) > 1000  # the red ball
    assert np.count_nonzero((r < 80) & (g < 80) & (b < 90)) > 100  # dark obstacles, text, outlines
    first_pose_color = np.array([0x1F, 0x77, 0xB4])  # the zigzag's line and markers
    assert np.count_nonzero(np.abs(rgb - first_pose_color).max(axis=-1) < 12) > 100
    assert sorted(p.name for p in tmp_path.iterdir()) == ["all.png"]  # no temporary file left


def test_refuses_to_overwrite_unless_asked(tmp_path):
    target = tmp_path / "world.png"
    target.write_bytes(b"keep me")
    with pytest.raises(FileExistsError) as refused:
        draw.draw_world(resolved(every_shape_world()), target)
    assert str(target) in str(refused.value) and "--force" in str(refused.value)
    assert target.read_bytes() == b"keep me"
    draw.draw_world(resolved(every_shape_world()), target, overwrite=True)
    assert_png_with_content(target)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["world.png"]


def test_a_failed_save_leaves_nothing_behind(tmp_path, monkeypatch):
    def broken(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(draw.Figure, "savefig", broken)
    with pytest.raises(OSError, match="disk full"):
        draw.draw_world(resolved(every_shape_world()), tmp_path / "world.png")
    assert list(tmp_path.iterdir()) == []


def test_one_scatter_per_pose_set_so_ten_thousand_poses_stay_fast(tmp_path, monkeypatch):
    calls = []
    original = Axes3D.scatter

    def counting(self, *args, **kwargs):
        calls.append(len(np.atleast_1d(args[0])))
        return original(self, *args, **kwargs)

    monkeypatch.setattr(Axes3D, "scatter", counting)
    world = resolved(every_shape_world(random_poses=10_000))
    draw.draw_world(world, tmp_path / "crowded.png")
    sets = [s for g in world.geometries for s in g.poses()]
    assert sorted(calls) == sorted([len(s) for s in sets] + [1])  # + the zigzag's start marker
    assert 10_000 in calls
    assert_png_with_content(tmp_path / "crowded.png")


@pytest.mark.parametrize("shape,dims", [("cube", [2, 3, 4]), ("sphere", [3, 3, 3]), ("cylinder", [2, 2, 5]),
                                        ("torus", [6, 9, 3]), ("prism", [2, [[0, 0], [4, 0], [4, 3], [2, 1], [0, 3]]])])
def test_meshes_lie_on_their_solid_and_span_it(shape, dims):
    spec = parse_shape(shape, dims)
    faces, outline = draw.shape_mesh(spec)
    vertices = np.vstack(faces + outline)
    assert contains(spec, vertices, tolerance=1e-6).all()
    low, high = half_extents(spec)
    assert np.allclose(vertices.min(axis=0), low, atol=0.02 * np.ptp(high - low) + 1e-6)
    assert np.allclose(vertices.max(axis=0), high, atol=0.02 * np.ptp(high - low) + 1e-6)


def test_view_fits_the_content_not_the_boundaries_and_keeps_flat_worlds_readable():
    low, high = draw.content_bounds([np.array([[0, 0, 0], [100, 50, 1]], dtype=float)])
    span = high - low
    assert np.all(low <= [0, 0, 0]) and np.all(high >= [100, 50, 1])
    assert span[0] < 120  # the content, not 1800 m of world_boundaries
    assert span[2] >= draw.MIN_AXIS_SHARE * 100  # a flat world is widened, not squashed into a line
    assert np.allclose(draw.content_bounds([])[1] - draw.content_bounds([])[0], 2.0)


def test_alpha_zero_geometries_stay_visible():
    assert draw._face_alpha(0.0) >= draw.MIN_ALPHA > 0
    assert draw._face_alpha(1.0) <= draw.MAX_ALPHA < 1


def test_cli_draw_writes_refuses_and_forces(tmp_path, capsys):
    world = tmp_path / "Shapes" / "All.json"
    world.parent.mkdir()
    world.write_text(json.dumps(every_shape_world()))
    out = tmp_path / "pictures" / "all.png"
    out.parent.mkdir()

    status, stdout, err = magna(capsys, "world", "draw", world, "-o", out, "--elev", "40", "--azim", "-30")
    assert status == 0, err
    assert stdout.strip() == str(out)
    assert_png_with_content(out)
    first = out.read_bytes()

    status, stdout, err = magna(capsys, "world", "draw", world, "-o", out, "--seed", "5")
    assert status == 2 and stdout == ""
    assert err.splitlines() == [f"magna world: {out} already exists; pass --force to replace it"]
    assert out.read_bytes() == first

    status, stdout, err = magna(capsys, "world", "draw", world, "-o", out, "--seed", "5", "--force")
    assert status == 0, err
    assert out.read_bytes() != first  # another seed, other random poses
    assert_png_with_content(out)
    assert sorted(p.name for p in out.parent.iterdir()) == ["all.png"]


def test_cli_draw_refuses_bad_output_names(tmp_path, capsys):
    world = tmp_path / "W" / "S.json"
    world.parent.mkdir()
    world.write_text(json.dumps(every_shape_world()))
    status, _, err = magna(capsys, "world", "draw", world, "-o", tmp_path / "nowhere" / "x.png")
    assert status == 2 and "does not exist" in err
    status, _, err = magna(capsys, "world", "draw", world, "-o", tmp_path / "x.jpg")
    assert status == 2 and "PNG" in err


@pytest.mark.parametrize("name", ["Gym/1Obs_Central_Cylinder.json", "Delivery/Delivery.json"])
def test_corpus_worlds_draw(name, tmp_path, capsys):
    path = CORPUS / "Worlds" / name
    assert path.is_file(), f"the ROS-MAGNA corpus is missing: {path}"
    status, _, err = magna(capsys, "world", "draw", path, "-o", tmp_path / "w.png")
    assert status == 0, err
    assert_png_with_content(tmp_path / "w.png")
