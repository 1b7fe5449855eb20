"""The client against a real shapeid-server: every call, inputs of every kind giving the
descriptor and label of the float32 xyz they hold, errors as exceptions with their codes,
deadlines, retries, chunking and one client shared by 16 threads."""

import concurrent.futures
import io
import os
import subprocess
import time

import grpc
import numpy as np
import pytest

import shapeid
from conftest import SHAPES, shape
from test_clouds import LAYOUTS, ros1_message, ros2_message

QUERY = shape(1, 999)  # a ball


def variants(points):
    """`points` (float32) as everything a robot may hold, by name."""
    wide = np.concatenate([points, np.zeros((len(points), 2), np.float32)], axis=1)
    out = {
        "float64": points.astype(np.float64),
        "fortran": np.asfortranarray(points),
        "strided": np.repeat(points, 3, axis=0)[1::3],
        "view-of-N-x-5": wide[:, :3],
        "big-endian": points.astype(">f8"),
        "pc2-ros1-xyzi16": ros1_message(points, LAYOUTS["xyzi16"]),
        "pc2-ros1-padded32-big-endian": ros1_message(points, LAYOUTS["padded32"], True),
        "pc2-ros2-float64": ros2_message(points, LAYOUTS["xyz64"]),
        "pc2-ros2-organized": ros2_message(points, LAYOUTS["xyzi16"], height=32,
                                           row_padding=4),
    }
    try:
        import open3d
    except ImportError:
        pass
    else:
        cloud = open3d.geometry.PointCloud()
        cloud.points = open3d.utility.Vector3dVector(points.astype(np.float64))
        out["open3d"] = cloud
    return out


def test_every_input_kind_gives_the_same_descriptor(client):
    reference = client.describe(QUERY)
    assert reference.descriptor_spec.startswith("dfsd:")
    assert reference.values.dtype == np.float32 and len(reference.values) == 240
    assert reference.num_points == 1024
    inputs = variants(QUERY)
    assert "open3d" in inputs, "python3-open3d must be installed (tools/install-deps.sh)"
    for name, cloud in inputs.items():
        got = client.describe(cloud)
        assert got.num_points == 1024, name
        assert np.array_equal(got.values, reference.values), name


def test_every_input_kind_gives_the_same_classification(client, trained):
    reference = client.classify(trained["name"], QUERY, k=3)
    assert reference.label == "ball"
    for name, cloud in variants(QUERY).items():
        got = client.classify(trained["name"], cloud, k=3)
        assert got.neighbors == reference.neighbors, name
        assert (got.label, got.votes, got.confidence) == (
            reference.label, reference.votes, reference.confidence), name


def test_nans_dropped_give_the_cloud_without_them(client):
    with_nans = np.concatenate([QUERY, np.full((5, 3), np.nan, np.float32)])
    message = ros1_message(with_nans[:1024], LAYOUTS["xyzi16"], height=32)
    with pytest.raises(ValueError, match="drop_non_finite=True"):
        client.describe(with_nans)
    assert np.array_equal(client.describe(with_nans, drop_non_finite=True).values,
                          client.describe(QUERY).values)
    dropped = client.describe(message, drop_non_finite=True)
    assert dropped.num_points == 1024


def test_point_cloud2_streamed_and_trained_through_the_server_decoder(server, client, gallery):
    """Forwarded PointCloud2 bytes in chunks of 700 x point_step (cut inside points' rows of
    a padded organized cloud), in a train stream of one layout and one mixing layouts."""
    points = shape(1, 42, 5000)
    reference = client.describe(points).values
    organized = ros2_message(points, LAYOUTS["padded32"], height=50, row_padding=12)
    big_endian64 = ros1_message(points, LAYOUTS["xyz64"], True)
    small = shapeid.Client(server.address, chunk_points=700)
    try:
        for message in (organized, big_endian64):
            assert np.array_equal(small.describe(message).values, reference)
        one_layout = small.train(gallery, [organized, organized], "ball")
        mixed = small.train(gallery, [organized, big_endian64, points], "ball")
        assert len(one_layout.sample_ids) == 2 and mixed.gallery_sample_count == 5
        answer = client.classify(gallery, points, k=5)
        assert [n.distance for n in answer.neighbors] == [0.0] * 5
    finally:
        small.close()


def test_layout_the_client_lets_through_is_the_servers_invalid_argument(client, trained):
    # Overlapping coordinates are declarable (each fits in point_step); the server refuses
    # them, naming the field, as InvalidArgumentError (a ValueError).
    message = ros2_message(QUERY, LAYOUTS["xyzi16"])
    next(f for f in message.fields if f.name == "y").offset = 0  # reads x again
    for call in (lambda: client.describe(message),
                 lambda: client.classify(trained["name"], message)):
        with pytest.raises(shapeid.InvalidArgumentError,
                           match=r"point layout: x and y overlap \(offsets 0 and 0\)") as e:
            call()
        assert e.value.code == grpc.StatusCode.INVALID_ARGUMENT


def test_non_finite_in_a_forwarded_point_cloud2_named_by_the_client(client):
    points = QUERY.copy()
    points[40, 1] = np.nan
    message = ros1_message(points, LAYOUTS["xyzi16"], height=32)
    with pytest.raises(ValueError, match=r"1 of 1024 points have a NaN or infinite coordinate "
                                         r"\(the first: point 40 \(row 1, column 8\)"):
        client.describe(message)
    dropped = client.describe(message, drop_non_finite=True)  # dropped by the server
    assert dropped.num_points == 1023
    assert np.array_equal(dropped.values,
                          client.describe(np.delete(QUERY, 40, axis=0)).values)


def test_mis_declared_point_cloud2s_are_refused_not_misread(client, trained):
    """Issue 39's layouts, each of which gave wrong labels at 100 % confidence: refused
    before anything is sent, dropping non-finite points or not (the server refuses the same
    layouts sent raw: test_wire.py)."""
    points = QUERY[:48]
    short_step = ros2_message(points, LAYOUTS["xyzi16"])
    short_step.point_step = 12
    xyz_only32 = ros2_message(points, (32, ("x", 0, "f4"), ("y", 4, "f4"), ("z", 8, "f4")))
    xyz_only32.point_step = 16
    swapped = ros2_message(points, LAYOUTS["xyzi16"], big_endian=True)
    swapped.is_bigendian = False
    narrow = ros2_message(points, (32, ("x", 0, "f4"), ("y", 8, "f4"), ("z", 16, "f4")))
    wide = ros2_message(points, LAYOUTS["xyz64"])
    for f in narrow.fields:
        f.datatype = shapeid.clouds.FLOAT64
    for f in wide.fields[:3]:
        f.datatype = shapeid.clouds.FLOAT32
    cases = [(short_step, r"field 'intensity' at offset 12 \(4 bytes\) does not fit in "
                          r"point_step 12"),
             (xyz_only32, r"row_step 1536 leaves 768 bytes after width 48 x point_step 16"),
             (swapped, r"the points look byte-swapped: .* is is_bigendian right\?$"),
             (narrow, r"the points look like FLOAT32 data declared FLOAT64"),
             (wide, r"the points look like FLOAT64 data declared FLOAT32")]
    for message, error in cases:
        for drop in (False, True):
            with pytest.raises(ValueError, match=error):
                client.classify(trained["name"], message, drop_non_finite=drop)
            with pytest.raises(ValueError, match=error):
                client.describe(message, drop_non_finite=drop)


# ---------------------------------------------------------------------------------------------
# The sensor's frame

def camera_optical(points):
    """Upright points (z up) as a camera looking along +x sees them in its optical frame
    (x right, y down, z forward): (-y, -z, x)."""
    return np.stack([-points[:, 1], -points[:, 2], points[:, 0]], axis=1).astype(np.float32)


def test_camera_optical_frame_with_up_gives_the_upright_label(client):
    client.create_gallery("upright", spec="dfsd:frame=upright", k=1)
    try:
        clouds = [shape(kind, 300 + 10 * i + kind) for i in range(3) for kind in range(3)]
        client.train("upright", clouds, [SHAPES[kind] for _ in range(3) for kind in range(3)])
        for kind in range(3):
            upright = shape(kind, 7000 + kind)
            expected = client.classify("upright", upright).label
            assert expected == SHAPES[kind]
            camera = camera_optical(upright)
            assert client.classify("upright", camera, up=(0, -1, 0)).label == expected
            message = ros1_message(camera, LAYOUTS["xyzi16"])
            assert client.classify("upright", message, up=[0, -1, 0]).label == expected
        # the frame matters to this descriptor: the camera's points as they are differ
        plate = shape(0, 7000)
        upright = client.describe(plate, gallery="upright").values
        assert not np.allclose(client.describe(camera_optical(plate), gallery="upright").values,
                               upright, atol=1e-2)
        assert np.allclose(client.describe(camera_optical(plate), gallery="upright",
                                           up=(0, -1, 0)).values, upright, atol=1e-4)
    finally:
        client.delete_gallery("upright")


def rotation(axis, degrees):
    c, s = np.cos(np.radians(degrees)), np.sin(np.radians(degrees))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    r = np.eye(3)
    r[i, i], r[i, j], r[j, i], r[j, j] = c, -s, s, c
    return r


def test_rigid_transform_gives_the_descriptor_of_the_gallery_frame_cloud(client, gallery):
    spec = "dfsd:frame=upright"
    target = shape(0, 11).astype(np.float64)          # a plate, in the gallery's frame
    r = rotation(0, 35) @ rotation(2, -70)
    t = np.array([0.4, -2.0, 1.25])
    sensor = ((target - t) @ r).astype(np.float32)  # R^T (p - t): so that R p' + t = p
    tf = np.eye(4)
    tf[:3, :3], tf[:3, 3] = r, t
    reference = client.describe(target.astype(np.float32), spec=spec).values
    for transform in (tf, tf[:3], tf.tolist()):
        got = client.describe(sensor, spec=spec, transform=transform).values
        assert np.allclose(got, reference, atol=1e-4), np.abs(got - reference).max()
    assert not np.allclose(client.describe(sensor, spec=spec).values, reference, atol=1e-2)
    client.train(gallery, sensor, "plate", transform=tf)  # train takes the frame too
    assert client.classify(gallery, target.astype(np.float32)).neighbors[0].distance < 1e-3


def test_sensor_frame_refusals(client, trained):
    name = trained["name"]
    scaled = np.hstack([2 * np.eye(3), np.zeros((3, 1))])
    with pytest.raises(shapeid.InvalidArgumentError,
                       match=r"sensor transform: R is not a rotation \(R R\^T differs from I "
                             r"by 3; scaling and shear are not rigid\)") as e:
        client.classify(name, QUERY, transform=scaled)
    assert e.value.code == grpc.StatusCode.INVALID_ARGUMENT
    with pytest.raises(shapeid.InvalidArgumentError, match=r"sensor up: \(0, 0, 0\) is not a "
                                                            r"direction"):
        client.describe(QUERY, up=(0, 0, 0))
    # refused here, before anything is sent
    with pytest.raises(ValueError, match="give up or transform, not both"):
        client.classify(name, QUERY, up=(0, 0, 1), transform=np.eye(4))
    not_affine = np.eye(4)
    not_affine[3, 2] = 1
    with pytest.raises(ValueError, match=r"last row is \[0.0, 0.0, 1.0, 1.0\]"):
        client.describe(QUERY, transform=not_affine)
    with pytest.raises(ValueError, match=r"3 x 4 or 4 x 4 \(\[R \| t\]\), got shape \(3, 3\)"):
        client.train(name, QUERY, "ball", transform=np.eye(3))
    with pytest.raises(ValueError, match=r"up must be 3 numbers"):
        client.classify(name, QUERY, up=(0, 1))
    # Finite as a double, infinite in the float32 the points are moved in: the transform is
    # named, not the points.
    far = np.hstack([np.eye(3), [[1e39], [0], [0]]])
    with pytest.raises(shapeid.InvalidArgumentError,
                       match=r"sensor transform: row 0 column 3 \(transform\[3\]\) is 1e\+39, "
                             r"beyond float32's range \(\|value\| <= 3.40282e\+38\)"):
        client.classify(name, QUERY, transform=far)


def test_train_classify_get_list_delete(client):
    created = client.create_gallery("lifecycle", spec="rphsd:bins=30", k=3,
                                    weighting="distance", scaling="zscore")
    assert created.name == "lifecycle"
    assert created.descriptor_spec == "rphsd:refs=cubic27,bins=30,variant=complete"
    assert (created.dimension, created.k, created.weighting, created.scaling) == (
        81, 3, "distance", "zscore")
    assert created.sample_count == 0 and created.create_time.year >= 2024

    clouds = [shape(kind, 200 + 10 * i + kind) for i in range(4) for kind in range(3)]
    labels = [SHAPES[kind] for _ in range(4) for kind in range(3)]
    ids = [1000 + i for i in range(12)]
    ids[5] = 0  # the server assigns this one
    trained = client.train("lifecycle", clouds, labels, ids=ids)
    assert trained.sample_ids[:5] == ids[:5] and trained.sample_ids[6:] == ids[6:]
    assert trained.sample_ids[5] >= 1 << 63
    assert trained.gallery_sample_count == 12
    assert trained.gallery_version > created.version
    assert trained.describe_seconds > 0

    gallery = client.get_gallery("lifecycle")
    assert gallery.sample_count == 12 and gallery.version == trained.gallery_version
    assert gallery.label_counts == {"ball": 4, "plate": 4, "rod": 4}
    assert list(gallery.label_counts) == sorted(gallery.label_counts)
    assert "lifecycle" in [g.name for g in client.list_galleries()]

    label_of = dict(zip(trained.sample_ids, labels))
    for kind in range(3):
        answer = client.classify("lifecycle", shape(kind, 5000 + kind, 2000))
        assert answer.label == SHAPES[kind] and not answer.unknown
        assert answer.num_points == 2000 and len(answer.neighbors) == 3
        distances = [n.distance for n in answer.neighbors]
        assert distances == sorted(distances)
        assert all(label_of[n.sample_id] == n.label for n in answer.neighbors)
        assert answer.votes[0].label == answer.label
        assert 0 < answer.confidence <= 1
        assert answer.describe_seconds > 0 and answer.search_seconds > 0
        assert not answer.approximate
        assert len(client.classify("lifecycle", shape(kind, 1), k=1).neighbors) == 1

    removed = client.remove_samples("lifecycle", ids=[1000], labels="rod")
    assert (removed.removed, removed.remaining) == (5, 7)
    assert client.delete_gallery("lifecycle") == 7
    with pytest.raises(shapeid.NotFoundError):
        client.get_gallery("lifecycle")


def test_train_takes_one_cloud_one_label_or_a_batch(client, gallery):
    assert client.train(gallery, QUERY, "ball").gallery_sample_count == 1
    batch = np.stack([shape(0, 1), shape(0, 2)])  # (2, 1024, 3)
    assert client.train(gallery, batch, "plate").gallery_sample_count == 3
    with pytest.raises(ValueError, match="2 clouds but 3 labels"):
        client.train(gallery, batch, ["a", "b", "c"])
    with pytest.raises(ValueError, match=r"labels\[1\] is ''"):
        client.train(gallery, batch, ["a", ""])
    with pytest.raises(ValueError, match=r"clouds\[1\]: the array has shape \(5, 2\)"):
        client.train(gallery, [QUERY, np.zeros((5, 2))], "x")
    with pytest.raises(TypeError, match=r"clouds\[0\]: the array has dtype int64"):
        client.train(gallery, [np.zeros((5, 3), np.int64)], "x")
    assert client.get_gallery(gallery).sample_count == 3  # nothing sent by the refusals


def test_provenance_comes_back_with_neighbors_and_list_samples(client, gallery):
    batch = [shape(0, 11), shape(1, 12), shape(2, 13)]
    trained = client.train(gallery, batch, ["plate", "ball", "rod"],
                           sources=["scans/plate.ply", "scans/ball.pcd", ""],
                           metadata=[{"camera": "d435", "take": "1"}, {}, {"camera": "l515"}])
    answer = client.classify(gallery, QUERY, k=3)
    by_id = {n.sample_id: n for n in answer.neighbors}
    ball = by_id[trained.sample_ids[1]]
    assert (ball.label, ball.source, ball.metadata) == ("ball", "scans/ball.pcd", {})
    plate = by_id[trained.sample_ids[0]]
    assert (plate.source, plate.metadata) == ("scans/plate.ply", {"camera": "d435", "take": "1"})
    assert by_id[trained.sample_ids[2]].source == ""

    listed = list(client.list_samples(gallery, page_size=1))  # three pages of one
    assert [s.sample_id for s in listed] == sorted(trained.sample_ids)
    assert {s.sample_id: (s.label, s.views, s.source, s.metadata) for s in listed} == {
        trained.sample_ids[0]: ("plate", 1, "scans/plate.ply", {"camera": "d435", "take": "1"}),
        trained.sample_ids[1]: ("ball", 1, "scans/ball.pcd", {}),
        trained.sample_ids[2]: ("rod", 1, "", {"camera": "l515"}),
    }
    assert [s.label for s in client.list_samples(gallery, label="rod")] == ["rod"]

    with pytest.raises(ValueError, match="3 clouds but 2 sources"):
        client.train(gallery, batch, "x", sources=["a", "b"])
    with pytest.raises(TypeError, match=r"metadata\[0\] is .*dict of str -> str"):
        client.train(gallery, batch, "x", metadata=[{"k": 1}, {}, {}])
    with pytest.raises(shapeid.InvalidArgumentError, match="more than the limit of 4096"):
        client.train(gallery, QUERY, "x", sources=["s" * 4097])
    with pytest.raises(shapeid.InvalidArgumentError, match="was not given by this gallery"):
        client._unary(True, client._stub.ListSamples,
                      shapeid.client._pb.ListSamplesRequest(gallery=gallery, page_token="1.2"),
                      None)
    assert client.get_gallery(gallery).sample_count == 3  # nothing sent by the refusals


def test_augmentation_and_reject_distance(client):
    created = client.create_gallery("augmented", augmentation=shapeid.Augmentation(views=2),
                                    reject_distance=1e-9)
    assert created.augmentation.views == 2 and created.reject_distance == 1e-9
    client.train("augmented", [shape(0, 1), shape(2, 2)], ["plate", "rod"])
    assert client.get_gallery("augmented").vector_count == 6
    plain = client.train("augmented", shape(1, 3), "ball",
                         augmentation=shapeid.Augmentation(views=0))
    assert client.get_gallery("augmented").vector_count == 7
    assert plain.gallery_sample_count == 3
    answer = client.classify("augmented", shape(1, 4))
    assert answer.unknown and answer.label == "unknown" and answer.confidence == 0
    assert created.augmentation.mix == "camera"
    varied = client.create_gallery("varied", augmentation=shapeid.Augmentation(views=3,
                                                                                mix="varied"))
    assert varied.augmentation.mix == "varied" and varied.augmentation.views == 3
    with pytest.raises(ValueError, match="expected one of camera, varied"):
        client.create_gallery("blurry", augmentation=shapeid.Augmentation(views=3, mix="blurry"))
    client.delete_gallery("varied")
    client.delete_gallery("augmented")


def test_a_gallery_learns_its_head_and_the_answer_says_so(client, gallery):
    # The test server runs with shapeid-server's default --learn=mlp: a gallery of 20 samples
    # or more gets a trained head once it has been quiet for 2 s.
    clouds = [shape(kind, 500 + 10 * i + kind, 256) for i in range(8) for kind in range(3)]
    client.train(gallery, clouds, [SHAPES[kind] for _ in range(8) for kind in range(3)])
    deadline = time.monotonic() + 60
    while client.get_gallery(gallery).head is None and time.monotonic() < deadline:
        time.sleep(0.1)
    info = client.get_gallery(gallery)
    assert info.head is not None, "no head 60 s after training"
    assert info.head.answers and info.head.fitted_version == info.version
    assert info.head.fitted_samples + info.head.holdout_samples == 24
    assert 0 <= info.head.holdout_accuracy <= 1 and info.head.fit_seconds > 0
    answer = client.classify(gallery, shape(1, 7, 256))
    assert answer.by_head and answer.label == "ball" and answer.neighbors


def test_big_clouds_stream_in_chunks_with_the_same_answers(server, client, trained):
    points = shape(1, 42, 5000)
    small = shapeid.Client(server.address, chunk_points=700)  # 5000 points: 8 chunks
    try:
        assert np.array_equal(small.describe(points).values, client.describe(points).values)
        assert (small.classify(trained["name"], points, k=3).neighbors
                == client.classify(trained["name"], points, k=3).neighbors)
        small.create_gallery("chunked")
        small.train("chunked", [points, shape(0, 43, 3000)], ["ball", "plate"])
        client.create_gallery("whole")
        client.train("whole", [points, shape(0, 43, 3000)], ["ball", "plate"])
        assert (small.classify("chunked", QUERY).neighbors[0].distance
                == client.classify("whole", QUERY).neighbors[0].distance)
    finally:
        small.close()


def test_export_import_round_trip_and_cli_compatibility(client, trained, tmp_path):
    path = tmp_path / "shapes.shapeid"
    assert client.export_gallery(trained["name"], path) == 12
    assert path.read_bytes().startswith(b"SHAPEIDG")
    assert sorted(os.listdir(tmp_path)) == ["shapes.shapeid"]  # no temporary file left

    imported = client.import_gallery(path, name="shapes-copy")
    original = client.get_gallery(trained["name"])
    assert (imported.name, imported.sample_count, imported.label_counts) == (
        "shapes-copy", 12, original.label_counts)
    assert (client.classify("shapes-copy", QUERY, k=3).neighbors
            == client.classify(trained["name"], QUERY, k=3).neighbors)

    buffer = io.BytesIO()
    assert client.export_gallery("shapes-copy", buffer) == 12
    buffer.seek(0)
    with pytest.raises(shapeid.AlreadyExistsError):
        client.import_gallery(buffer)

    # The CLI writes the same bytes and reads ours.
    cli_file = tmp_path / "cli.shapeid"
    subprocess.run([os.environ["SHAPEID_CLI"], "--server", client.target, "--quiet",
                    "gallery", "export", trained["name"], str(cli_file)], check=True)
    assert cli_file.read_bytes() == path.read_bytes()
    subprocess.run([os.environ["SHAPEID_CLI"], "--server", client.target, "--quiet",
                    "gallery", "import", str(path), "--name", "shapes-by-cli"], check=True,
                   stdout=subprocess.DEVNULL)
    assert client.get_gallery("shapes-by-cli").sample_count == 12
    for name in ("shapes-copy", "shapes-by-cli"):
        client.delete_gallery(name)


def test_import_of_damaged_files(client, trained, tmp_path):
    path = tmp_path / "g.shapeid"
    client.export_gallery(trained["name"], path)
    data = path.read_bytes()
    (tmp_path / "short").write_bytes(data[:len(data) // 2])
    with pytest.raises(shapeid.DataLossError, match=r"short: ends inside chunk \d+"):
        client.import_gallery(tmp_path / "short", name="never")
    (tmp_path / "other").write_bytes(b"# .xyz\n0 0 0\n")
    with pytest.raises(ValueError, match="is not a shapeid gallery export"):
        client.import_gallery(tmp_path / "other", name="never")
    flipped = bytearray(data)
    flipped[-3] ^= 0xFF  # inside the trailer's CRC
    (tmp_path / "flipped").write_bytes(bytes(flipped))
    with pytest.raises((shapeid.DataLossError, shapeid.InvalidArgumentError)):
        client.import_gallery(tmp_path / "flipped", name="never")
    assert "never" not in [g.name for g in client.list_galleries()]
    with pytest.raises(shapeid.NotFoundError):
        client.export_gallery("no-such-gallery", tmp_path / "nothing.shapeid")
    assert not (tmp_path / "nothing.shapeid").exists()


def test_list_descriptors(client):
    kinds = {d.kind: d for d in client.list_descriptors()}
    assert set(kinds) == {"rphsd", "comsd", "cnsd", "dfsd", "learned"}
    assert kinds["dfsd"].default_spec == "dfsd:grid=12,order=8,frame=box,fields=both,size=0"
    assert kinds["dfsd"].default_dimension == 240
    assert (kinds["rphsd"].default_spec, kinds["rphsd"].default_dimension) == (
        "rphsd:refs=cubic27,bins=100,variant=complete", 81)
    for d in kinds.values():
        assert d.summary and all(p.help for p in d.parameters)
        expected = ",".join("%s=%s" % (p.name, p.default_value) for p in d.parameters
                            if (d.kind, p.name) not in {("dfsd", "up"), ("dfsd", "smooth")})
        assert d.default_spec == "%s:%s" % (d.kind, expected)


def test_health_stats_and_log_level(client, trained):
    health = client.health()
    assert health.serving and health.status == "SERVING"
    stats = client.get_server_stats()
    assert stats.version and stats.state == "serving" and stats.uptime_seconds > 0
    assert trained["name"] in [g.name for g in stats.galleries]
    methods = {m.method: m for m in stats.methods}
    assert methods["ClassifyCloud"].calls >= 1
    assert methods["ClassifyCloud"].latency_p50_seconds > 0
    assert {w.lane for w in stats.work} == {"cheap", "heavy", "store"}
    level = client.set_log_level("warning")
    assert level.level == "warning"
    assert client.set_log_level(level.previous_level).previous_level == "warning"
    with pytest.raises(shapeid.InvalidArgumentError):
        client.set_log_level("loud")


def test_server_errors_are_exceptions_with_code_and_message(client, trained, gallery):
    with pytest.raises(shapeid.NotFoundError) as caught:
        client.classify("nope", QUERY)
    assert caught.value.code == grpc.StatusCode.NOT_FOUND
    assert "nope" in caught.value.message and str(caught.value).startswith("NOT_FOUND: ")
    assert isinstance(caught.value, shapeid.ShapeidError) and isinstance(caught.value, LookupError)

    with pytest.raises(shapeid.AlreadyExistsError):
        client.create_gallery(trained["name"])
    with pytest.raises(shapeid.InvalidArgumentError, match=r"\[A-Za-z0-9\]") as caught:
        client.create_gallery("no spaces")
    assert isinstance(caught.value, ValueError)
    with pytest.raises(shapeid.FailedPreconditionError, match="has no samples"):
        client.classify(gallery, QUERY)
    with pytest.raises(shapeid.InvalidArgumentError, match="cloud has 2 points"):
        client.describe(QUERY[:2])
    with pytest.raises(shapeid.InvalidArgumentError):
        client.describe(QUERY, spec="nosuchdescriptor")
    with pytest.raises(shapeid.NotFoundError):
        client.train("nope", QUERY, "ball")
    with pytest.raises(shapeid.NotFoundError):
        client.remove_samples(trained["name"], ids=[12345])
    with pytest.raises(ValueError, match="weighting must be one of uniform, distance"):
        client.create_gallery("x", weighting="heavy")
    assert client.get_gallery(trained["name"]).sample_count == 12  # unchanged by it all


def test_sample_id_collision_fails_the_whole_stream(client, gallery):
    client.train(gallery, QUERY, "ball", ids=[7])
    with pytest.raises(shapeid.AlreadyExistsError):
        client.train(gallery, [shape(0, 1), QUERY], ["plate", "ball"], ids=[8, 7])
    assert client.get_gallery(gallery).sample_count == 1  # all or nothing


def test_deadlines(server, client):
    big = shape(1, 8, 300_000)  # ~0.1 s to describe: far beyond the deadlines below
    with pytest.raises(shapeid.DeadlineExceededError) as caught:
        client.describe(big, timeout=0.01)
    assert caught.value.code == grpc.StatusCode.DEADLINE_EXCEEDED
    assert isinstance(caught.value, TimeoutError)
    with shapeid.Client(server.address, deadline=0.01) as hasty:
        with pytest.raises(shapeid.DeadlineExceededError):
            hasty.describe(big)
        assert hasty.describe(big, timeout=30).num_points == 300_000  # a per-call timeout wins
    with pytest.raises(ValueError, match="timeout must be positive"):
        client.health(timeout=0)


def test_retries_of_idempotent_calls_only():
    # Nothing listens on port 1: every attempt fails UNAVAILABLE at once, so a call's time is
    # its backoff: 0.25 + 0.5 s over 3 attempts, 0 when sent once.
    with shapeid.Client("127.0.0.1:1", initial_backoff=0.25, max_attempts=3) as down:
        def seconds(call, *args, **kwargs):
            start = time.monotonic()
            with pytest.raises(shapeid.UnavailableError) as caught:
                call(*args, **kwargs)
            assert isinstance(caught.value, ConnectionError)
            return time.monotonic() - start

        assert seconds(down.get_gallery, "g") >= 0.75
        assert seconds(down.create_gallery, "g") < 0.5  # not idempotent: sent once
        assert seconds(down.train, "g", QUERY, "ball") < 0.5  # ids left to the server: once
        assert seconds(down.train, "g", QUERY, "ball", ids=[5]) >= 0.75  # every id chosen
        # The backoff stops at the deadline: 0.25 s, then 0.5 s more would pass 0.4 s.
        assert 0.25 <= seconds(down.classify, "g", QUERY, timeout=0.4) < 0.6
    with shapeid.Client("127.0.0.1:1", initial_backoff=0.25, max_attempts=1) as once:
        assert seconds(once.get_gallery, "g") < 0.5


def test_options_are_checked():
    for kwargs, message in [({"max_attempts": 0}, "max_attempts must be an integer >= 1"),
                            ({"chunk_points": 0}, "chunk_points must be an integer >= 1"),
                            ({"deadline": -1}, "deadline must be positive"),
                            ({"api_key": "key\n"}, "a stray newline"),
                            ({"request_id": "job 7"}, "a request id is 1 to 128 characters"),
                            ({"load_balancing": "random"}, "round_robin or pick_first"),
                            ({"tls_server_name": "x"}, "TLS is off"),
                            ({"tls_cert_file": "c.pem"}, "needs its key"),
                            ({"tls_ca_file": "/nonexistent.pem"}, "cannot read the TLS CA file")]:
        with pytest.raises(ValueError, match=message):
            shapeid.Client("127.0.0.1:50051", **kwargs)
    with pytest.raises(ValueError, match="entry 2 '' is empty"):
        shapeid.Client("127.0.0.1:1,")
    with pytest.raises(ValueError, match=r"is neither HOST\[:PORT\] nor an IPv6 address"):
        shapeid.Client("a:b:c,127.0.0.1:5")
    with pytest.raises(ValueError, match="max_receive_bytes must be an integer from 1"):
        shapeid.Client("127.0.0.1:50051", max_receive_bytes=0)


def test_only_the_clients_own_receive_limit_is_called_its_own():
    class Refusal(grpc.RpcError):
        def __init__(self, details):
            self._details = details

        def code(self):
            return grpc.StatusCode.RESOURCE_EXHAUSTED

        def details(self):
            return self._details

    # gRPC words both sides' limits alike; the limit in the message tells them apart.
    server_side = shapeid.errors.from_rpc_error(
        Refusal("Received message larger than max (5000000 vs. 4194304)"), 1 << 20)
    assert isinstance(server_side, shapeid.ResourceExhaustedError)
    assert not server_side.client_limit
    assert server_side.message == "Received message larger than max (5000000 vs. 4194304)"
    own = shapeid.errors.from_rpc_error(
        Refusal("Received message larger than max (5000000 vs. 1048576)"), 1 << 20)
    assert own.client_limit
    assert own.message.startswith("the server's answer is 5000000 bytes, more than this "
                                  "client's receive limit of 1048576 bytes")


def test_hosts_without_a_port_get_the_default_port():
    from shapeid import _channel
    assert shapeid.DEFAULT_PORT == 50051
    for target, becomes in [("127.0.0.1", "127.0.0.1:50051"), ("localhost", "localhost:50051"),
                            ("[::1]", "[::1]:50051"), ("::1", "[::1]:50051"),
                            ("dns:///recognizer", "dns:///recognizer:50051"),
                            ("dns://8.8.8.8/recognizer", "dns://8.8.8.8/recognizer:50051"),
                            ("127.0.0.1,127.0.0.1:7", "ipv4:127.0.0.1:50051,127.0.0.1:7"),
                            ("[::1],[::1]:7", "ipv6:[::1]:50051,[::1]:7"),
                            # with a port, or no host: as they were
                            ("127.0.0.1:7", "127.0.0.1:7"), ("[::1]:7", "[::1]:7"),
                            ("dns:///recognizer:7", "dns:///recognizer:7"),
                            ("unix:///tmp/s.sock", "unix:///tmp/s.sock"),
                            ("ipv4:127.0.0.1:1,127.0.0.1:2", "ipv4:127.0.0.1:1,127.0.0.1:2")]:
        assert _channel.resolve(target).target == becomes, target
    assert _channel.resolve("127.0.0.1,127.0.0.2:7").authority == "127.0.0.1:50051"


def test_large_answers_are_read_and_the_clients_own_limit_is_named(client, server, gallery):
    # 1,000 samples with the largest provenance allowed (a source of 4,096 bytes, 64 pairs of
    # 4,096 bytes of keys and values): a default list_samples page and a classify(k=1000)
    # are about 8.6 MB each, past gRPC's default receive limit of 4 MiB.
    sources = [("/scans/%d/" % i).ljust(4096, "s") for i in range(1000)]
    metadata = {"k%02d" % k: chr(ord("a") + k % 26) * 61 for k in range(64)}
    client.train(gallery, [shape(i % 3, 5000 + i, 100) for i in range(1000)],
                 [SHAPES[i % 3] for i in range(1000)], ids=list(range(1, 1001)),
                 sources=sources, metadata=metadata)
    samples = list(client.list_samples(gallery))
    assert [s.sample_id for s in samples] == list(range(1, 1001))
    assert samples[-1].source == sources[-1] and samples[-1].metadata == metadata
    assert len(client.classify(gallery, QUERY, k=1000).neighbors) == 1000
    assert shapeid.MAX_RECEIVE_BYTES == 256 << 20

    # Over a smaller limit of the client's own: its refusal, said to be its own.
    with shapeid.Client(server.address, max_receive_bytes=1 << 20) as small:
        for call in (lambda: list(small.list_samples(gallery)),
                     lambda: small.classify(gallery, QUERY, k=1000)):
            with pytest.raises(shapeid.ResourceExhaustedError) as caught:
                call()
            assert caught.value.client_limit
            assert caught.value.code == grpc.StatusCode.RESOURCE_EXHAUSTED
            assert caught.value.message.startswith("the server's answer is ")
            assert ("bytes, more than this client's receive limit of 1048576 bytes: this "
                    "client refused it, not the server") in caught.value.message


def test_replica_lists_and_request_ids(server, trained):
    # The same server twice is a list of two replicas, balanced round_robin.
    with shapeid.Client("%s,%s" % (server.address, server.address), request_id="job-7") as c:
        assert c.classify(trained["name"], QUERY).label == "ball"
    with shapeid.Client(server.address, load_balancing="pick_first") as c:
        assert c.health().serving


def test_caller_ids(server, trained):
    # A robot of a fleet sharing one host names itself; the server accepts the metadata.
    with shapeid.Client(server.address, caller_id="arm-left.7") as c:
        assert c.classify(trained["name"], QUERY).label == "ball"
    for bad in ("arm left", "a/b", "x" * 65, "caf\u00e9"):
        with pytest.raises(ValueError, match="caller id"):
            shapeid.Client(server.address, caller_id=bad)


def test_one_client_shared_by_16_threads(client, trained):
    queries = [(kind, shape(kind, 7000 + i, 800)) for i in range(8) for kind in range(3)]
    reference = {id(q): client.classify(trained["name"], q, k=3) for _, q in queries}

    def work(item):
        kind, points = item
        return kind, id(points), client.classify(trained["name"], points, k=3)

    with concurrent.futures.ThreadPoolExecutor(16) as pool:
        results = list(pool.map(work, queries * 8))
    assert len(results) == 192
    for kind, key, answer in results:
        assert answer.label == SHAPES[kind]
        assert (answer.neighbors, answer.votes) == (reference[key].neighbors, reference[key].votes)
