"""Client.recognize_scene against a real shapeid-server: a table frame with a plate, a ball
and a rod on it, as an array, an Open3D cloud and organized PointCloud2 messages; objects found,
named and placed, indices into the frame as sent (non-finite points kept and counted),
segmentation parameters sent only when given, the sensor's frame, and errors."""

import numpy as np
import pytest

import shapeid
from conftest import SHAPES, shape
from test_client import camera_optical
from test_clouds import LAYOUTS, ros1_message, ros2_message

TABLE_Z = -0.5
SCALE = 0.05  # conftest's shapes are a few units across: 5 cm a unit makes tabletop objects
# Each object's center: floating 3 cm or more above the table, so that none of its points is
# within the plane distance (1 cm), and farther apart than the cluster tolerance (2 cm).
PLACES = {"plate": (0.1, 0.3, TABLE_Z + 0.04), "ball": (-0.3, -0.1, TABLE_Z + 0.08),
          "rod": (0.2, -0.3, TABLE_Z + 0.04)}
TABLE_POINTS = 121 * 121
OBJECT_POINTS = 3000
PACKED = (12, ("x", 0, "f4"), ("y", 4, "f4"), ("z", 8, "f4"))


def table_frame(nans=0, seed=0):
    """(frame, truth): a 1.2 m square table (1 cm grid at z = TABLE_Z) with the three shapes
    on it (conftest seeds 500-502, none trained), `nans` NaN rows among them at random
    places; truth maps "table" and each label to its rows' indices in the frame."""
    grid = np.linspace(-0.6, 0.6, 121)
    x, y = np.meshgrid(grid, grid)
    parts = [("table", np.stack([x.ravel(), y.ravel(), np.full(x.size, TABLE_Z)], axis=1))]
    for kind, label in enumerate(SHAPES):
        parts.append((label, SCALE * shape(kind, 500 + kind, OBJECT_POINTS) + PLACES[label]))
    points = np.concatenate([part for _, part in parts]).astype(np.float32)
    total = len(points) + nans
    missing = np.zeros(total, bool)
    missing[np.random.default_rng(seed).choice(total, nans, replace=False)] = True
    frame = np.full((total, 3), np.nan, np.float32)
    rows = np.flatnonzero(~missing)
    frame[rows] = points
    truth, start = {}, 0
    for label, part in parts:
        truth[label] = rows[start:start + len(part)].astype(np.uint32)
        start += len(part)
    return frame, truth


@pytest.fixture(scope="module")
def scene_gallery(client):
    """Three plates, balls and rods at the scene's scale (conftest seeds 400-432)."""
    client.create_gallery("scene-shapes")
    clouds = [SCALE * shape(kind, 400 + 10 * i + kind) for i in range(3) for kind in range(3)]
    client.train("scene-shapes", clouds, [SHAPES[kind] for _ in range(3) for kind in range(3)])
    yield "scene-shapes"
    client.delete_gallery("scene-shapes")


def assert_accounted(scene):
    """Every point sent is in one plane, one object or one of the counts."""
    assert scene.num_points == (sum(p.num_points for p in scene.planes) +
                                sum(o.num_points for o in scene.objects) +
                                scene.non_finite_points + scene.outside_region +
                                scene.in_small_clusters + scene.in_large_clusters)


def assert_table_scene(scene, truth, nans, with_indices=True):
    assert scene.num_points == TABLE_POINTS + 3 * OBJECT_POINTS + nans
    assert scene.non_finite_points == nans
    assert (scene.outside_region, scene.in_small_clusters, scene.in_large_clusters) == (0, 0, 0)
    assert len(scene.planes) == 1
    assert np.allclose(scene.planes[0].coefficients, [0, 0, 1, -TABLE_Z], atol=1e-4)
    assert scene.planes[0].num_points == TABLE_POINTS
    assert sorted(o.label for o in scene.objects) == sorted(SHAPES)
    for found in scene.objects:
        assert found.error == "" and not found.classification.unknown, found.label
        assert found.num_points == OBJECT_POINTS
        assert found.classification.neighbors[0].label == found.label
        assert np.linalg.norm(found.centroid - PLACES[found.label]) < 0.005, found.label
        assert np.allclose(found.box.center, found.centroid, atol=0.01)
        assert np.isclose(np.linalg.norm(found.box.orientation), 1.0, atol=1e-6)
        if with_indices:
            assert found.indices.dtype == np.uint32
            assert np.array_equal(found.indices, truth[found.label]), found.label
        else:
            assert found.indices is None
    # The boxes' extents, largest spread first: conftest's shapes at 5 cm a unit.
    sizes = {o.label: o.box.size for o in scene.objects}
    assert np.allclose(sizes["plate"], [0.2, 0.15, 0.01], atol=0.005)
    assert np.allclose(sizes["ball"], 0.1, atol=0.005)
    assert np.allclose(sizes["rod"], [0.3, 0.005, 0.005], atol=0.005)
    assert scene.segment_seconds > 0 and scene.classify_seconds > 0
    assert_accounted(scene)


def test_objects_found_named_placed_and_indexed_with_nans_kept(client, scene_gallery):
    frame, truth = table_frame(nans=359)
    with pytest.raises(ValueError, match="drop_non_finite=True"):  # classify refuses them
        client.classify(scene_gallery, frame)
    scene = client.recognize_scene(scene_gallery, frame, return_indices=True)
    assert_table_scene(scene, truth, 359)
    without = client.recognize_scene(scene_gallery, frame)
    assert_table_scene(without, truth, 359, with_indices=False)
    # Each object's answer is what classify gives for its points alone (turned by the
    # table's fitted normal, within float rounding of +z: the same neighbors).
    for found in scene.objects:
        alone = client.classify(scene_gallery, frame[found.indices])
        assert alone.label == found.label
        assert ([n.sample_id for n in alone.neighbors] ==
                [n.sample_id for n in found.classification.neighbors])
        assert np.allclose([n.distance for n in alone.neighbors],
                           [n.distance for n in found.classification.neighbors], rtol=1e-3)


def test_one_message_and_a_stream_of_chunks_get_the_same_answer(server, client, scene_gallery):
    frame, truth = table_frame(nans=40)

    def calls():
        methods = {m.method: m.calls for m in client.get_server_stats().methods}
        return methods.get("RecognizeSceneCloud", 0), methods.get("RecognizeScene", 0)

    before = calls()
    with shapeid.Client(server.address, chunk_points=len(frame)) as whole:
        one_message = whole.recognize_scene(scene_gallery, frame, return_indices=True)
    with shapeid.Client(server.address, chunk_points=1000) as small:
        streamed = small.recognize_scene(scene_gallery, frame, return_indices=True)
    assert calls() == (before[0] + 1, before[1] + 1)
    assert_table_scene(streamed, truth, 40)
    assert np.array_equal(streamed.planes[0].coefficients, one_message.planes[0].coefficients)
    for a, b in zip(streamed.objects, one_message.objects):
        assert a.label == b.label and np.array_equal(a.indices, b.indices)
        assert np.array_equal(a.centroid, b.centroid)


def test_every_input_kind_indices_count_every_point_sent(client, scene_gallery):
    """An organized 160 x 150 frame: an index is a pixel (row * width + column), NaN pixels
    included, whether the message is forwarded with its layout, already packed float32 (sent
    as it is) or an array."""
    frame, truth = table_frame(nans=160 * 150 - TABLE_POINTS - 3 * OBJECT_POINTS, seed=3)
    inputs = {
        "float64 array": frame.astype(np.float64),
        "ros1 xyzi16 organized": ros1_message(frame, LAYOUTS["xyzi16"], height=160),
        "ros2 packed organized": ros2_message(frame, PACKED, height=160),
        "ros2 float64 padded rows": ros2_message(frame, LAYOUTS["xyz64"], height=160,
                                                 row_padding=8),
    }
    import open3d
    cloud = open3d.geometry.PointCloud()
    cloud.points = open3d.utility.Vector3dVector(frame.astype(np.float64))
    inputs["open3d"] = cloud
    for name, cloud in inputs.items():
        scene = client.recognize_scene(scene_gallery, cloud, return_indices=True)
        try:
            assert_table_scene(scene, truth, 359)
        except AssertionError as e:
            raise AssertionError("%s: %s" % (name, e)) from None


def test_segmentation_parameters_are_sent_only_when_given(client, scene_gallery):
    frame, truth = table_frame()
    # 0 is sent, not taken for the default: no plane removed, the table is the largest object
    flat = client.recognize_scene(scene_gallery, frame, max_planes=0, return_indices=True)
    assert flat.planes == [] and len(flat.objects) == 4
    assert np.array_equal(flat.objects[0].indices, truth["table"])
    assert_accounted(flat)
    noise = client.recognize_scene(scene_gallery, frame, min_cluster_points=OBJECT_POINTS + 1)
    assert noise.objects == [] and noise.in_small_clusters == 3 * OBJECT_POINTS
    background = client.recognize_scene(scene_gallery, frame,
                                        max_cluster_points=OBJECT_POINTS - 1)
    assert background.objects == [] and background.in_large_clusters == 3 * OBJECT_POINTS
    # a region leaving out the rod (y = -0.3) and the table's near edge
    near = client.recognize_scene(scene_gallery, frame, region=((-1, -0.2, -1), (1, 1, 1)))
    assert sorted(o.label for o in near.objects) == ["ball", "plate"]
    beyond = int(np.count_nonzero(frame[truth["table"], 1] < np.float32(-0.2)))
    assert near.outside_region == OBJECT_POINTS + beyond and beyond == 121 * 40
    assert near.planes[0].num_points == TABLE_POINTS - beyond
    assert_accounted(near)
    # a plane distance wide enough to take the rod's (and the plate's lower) points
    wide = client.recognize_scene(scene_gallery, frame, plane_distance=0.05)
    assert wide.planes[0].num_points > TABLE_POINTS + OBJECT_POINTS
    # every other parameter, at the defaults, changes nothing; a seed gives one answer
    defaults = dict(max_planes=1, plane_distance=0.01, min_plane_share=0.05,
                    plane_iterations=1000, cluster_tolerance=0.02, min_cluster_points=100,
                    max_cluster_points=1_000_000, max_plane_tilt_degrees=15, seed=7)
    a = client.recognize_scene(scene_gallery, frame, **defaults)
    b = client.recognize_scene(scene_gallery, frame, **defaults)
    assert np.array_equal(a.planes[0].coefficients, b.planes[0].coefficients)
    assert [o.label for o in a.objects] == [o.label for o in b.objects]
    assert_table_scene(a, truth, 0, with_indices=False)


def test_the_sensors_frame(client, scene_gallery):
    frame, truth = table_frame(nans=10)
    camera = camera_optical(frame)  # (-y, -z, x): the table's up is -y
    scene = client.recognize_scene(scene_gallery, camera, up=(0, -1, 0), return_indices=True)
    # answers in the frame's own coordinates; the table's normal points up
    assert np.allclose(scene.planes[0].coefficients, [0, -1, 0, -TABLE_Z], atol=1e-4)
    assert sorted(o.label for o in scene.objects) == sorted(SHAPES)
    for found in scene.objects:
        assert np.array_equal(found.indices, truth[found.label])
        place = camera_optical(np.array([PLACES[found.label]]))[0]
        assert np.linalg.norm(found.centroid - place) < 0.005
    # Told an up 60 degrees off the table's normal, the table is no support (and no plane
    # within 15 degrees of level holds 30 % of the frame): the table is one more object,
    # unless tilts of up to 70 degrees are allowed.
    tilted_up = (np.sin(np.radians(60)), -np.cos(np.radians(60)), 0)
    sideways = client.recognize_scene(scene_gallery, camera, up=tilted_up, min_plane_share=0.3)
    assert sideways.planes == [] and len(sideways.objects) == 4
    assert sideways.objects[0].num_points == TABLE_POINTS
    allowed = client.recognize_scene(scene_gallery, camera, up=tilted_up, min_plane_share=0.3,
                                     max_plane_tilt_degrees=70)
    assert len(allowed.planes) == 1 and len(allowed.objects) == 3
    assert np.allclose(allowed.planes[0].coefficients, [0, -1, 0, -TABLE_Z], atol=1e-4)
    transform = np.eye(4)
    transform[:3, :3] = [[0, 0, 1], [-1, 0, 0], [0, -1, 0]]  # camera optical -> upright
    moved = client.recognize_scene(scene_gallery, camera, transform=transform)
    assert np.allclose(moved.planes[0].coefficients, [0, -1, 0, -TABLE_Z], atol=1e-4)
    assert sorted(o.label for o in moved.objects) == sorted(SHAPES)


def test_an_object_that_cannot_be_described_is_unknown_with_its_reason(client, scene_gallery):
    frame, _ = table_frame()
    stuck = np.tile(np.float32([0.5, 0.5, TABLE_Z + 0.2]), (150, 1))  # 150 identical points
    scene = client.recognize_scene(scene_gallery, np.concatenate([frame, stuck]),
                                   return_indices=True)
    assert len(scene.objects) == 4
    last = scene.objects[-1]  # the smallest
    assert last.error and last.label == "unknown" and last.classification.unknown
    assert last.classification.neighbors == [] and last.num_points == 150
    assert np.array_equal(last.indices, np.arange(len(frame), len(frame) + 150))
    assert sorted(o.label for o in scene.objects[:3]) == sorted(SHAPES)


def test_frames_without_objects(client, scene_gallery):
    frame, truth = table_frame()
    table = client.recognize_scene(scene_gallery, frame[truth["table"]])
    assert table.objects == [] and table.planes[0].num_points == TABLE_POINTS
    nothing = client.recognize_scene(scene_gallery, np.full((50, 3), np.nan, np.float32))
    assert (nothing.objects, nothing.planes, nothing.num_points,
            nothing.non_finite_points) == ([], [], 50, 50)
    empty = client.recognize_scene(scene_gallery, np.empty((0, 3), np.float32))
    assert (empty.objects, empty.planes, empty.num_points) == ([], [], 0)


def test_errors(client, scene_gallery, gallery):
    frame, _ = table_frame()
    with pytest.raises(shapeid.NotFoundError, match="nope"):
        client.recognize_scene("nope", frame)
    with pytest.raises(shapeid.FailedPreconditionError, match="has no samples"):
        client.recognize_scene(gallery, frame)  # a fresh, empty gallery
    # out of range: the server's InvalidArgumentError naming the parameter
    for kwargs, message in [({"cluster_tolerance": 0}, "cluster_tolerance is 0"),
                            ({"max_planes": 17}, r"max_planes is 17; it must be in \[0, 16\]"),
                            ({"min_plane_share": 1.5}, "min_plane_share is 1.5"),
                            ({"min_cluster_points": 10, "max_cluster_points": 5},
                             r"min_cluster_points is 10 and max_cluster_points 5"),
                            ({"region": ((0, 0, 0), (1, -1, 1))}, "the region's min"),
                            ({"up": (0, 0, 0)}, r"sensor up: \(0, 0, 0\) is not a direction")]:
        with pytest.raises(shapeid.InvalidArgumentError, match=message):
            client.recognize_scene(scene_gallery, frame, **kwargs)
    # refused here, before anything is sent
    for kwargs, message in [({"min_cluster_points": -1}, "min_cluster_points=-1"),
                            ({"plane_distance": "1 cm"}, "plane_distance='1 cm'"),
                            ({"region": (0, 0, 1, 1)}, r"region must be \(\(min x, y, z\)"),
                            ({"up": (0, 0, 1), "transform": np.eye(4)},
                             "give up or transform, not both")]:
        with pytest.raises(ValueError, match=message):
            client.recognize_scene(scene_gallery, frame, **kwargs)
    with pytest.raises(ValueError, match=r"point 3: x = 1e\+300 does not fit in a float32"):
        client.recognize_scene(scene_gallery, np.array([[0, 0, 0]] * 3 + [[1e300, 0, 0]]))
    with pytest.raises(TypeError, match="expected an N x 3 numpy array"):
        client.recognize_scene(scene_gallery, frame.tolist())
    message = ros2_message(frame, PACKED)
    message.row_step -= 1
    with pytest.raises(ValueError, match="PointCloud2: row_step"):
        client.recognize_scene(scene_gallery, message)
