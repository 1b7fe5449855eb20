"""The wire contract, through the generated stubs alone (shapeid.v1): what any gRPC client
written from proto/shapeid/v1/shapeid.proto may send, including what the shapeid.Client
never sends (malformed streams, non-finite points, odd chunkings), answered with the proto's
status codes. Formerly tests/python/interop_test.py (issue 3); its calls that the package
makes the ordinary way are tested through the package in test_client.py."""

import re

import grpc
import numpy as np
import pytest

from conftest import shape
from test_clouds import records
from shapeid.v1 import shapeid_pb2 as pb
from shapeid.v1 import shapeid_pb2_grpc as pb_grpc

TIMEOUT = 10


@pytest.fixture(scope="module")
def stub(server):
    channel = grpc.insecure_channel(server.address)
    yield pb_grpc.ShapeIdStub(channel)
    channel.close()


@pytest.fixture(scope="module")
def wire_gallery(stub):
    stub.CreateGallery(pb.CreateGalleryRequest(name="wire", descriptor_spec="rphsd:bins=30"),
                       timeout=TIMEOUT)
    stub.Train(train_requests("wire", [("plate", 0, shape(0, 1)), ("rod", 0, shape(2, 2))]),
               timeout=TIMEOUT)
    return "wire"


def chunks(points, size):
    for i in range(0, len(points), size):
        yield points[i:i + size].astype("<f4").tobytes()


def train_requests(gallery, samples, chunk=256, empty_chunk=False):
    yield pb.TrainRequest(header=pb.TrainHeader(gallery=gallery))
    for label, sample_id, points in samples:
        yield pb.TrainRequest(sample=pb.SampleHeader(label=label, sample_id=sample_id))
        if empty_chunk:  # the proto allows empty chunks
            yield pb.TrainRequest(points=pb.PointChunk(xyz=b""))
        for data in chunks(points, chunk):
            yield pb.TrainRequest(points=pb.PointChunk(xyz=data))


def classify_requests(gallery, points, chunk=1000):
    yield pb.ClassifyRequest(header=pb.ClassifyHeader(gallery=gallery, k=1,
                                                      expected_points=len(points)))
    for data in chunks(points, chunk):
        yield pb.ClassifyRequest(points=pb.PointChunk(xyz=data))


def rpc_error(code, call, *args):
    with pytest.raises(grpc.RpcError) as caught:
        call(*args, timeout=TIMEOUT)
    assert caught.value.code() == code, caught.value.details()
    return caught.value.details() or ""


def test_describe_is_independent_of_chunking(stub):
    points = shape(1, 5, 1000)

    def describe(size):
        def requests():
            yield pb.DescribeRequest(header=pb.DescribeHeader(descriptor_spec="rphsd:bins=30"))
            for data in chunks(points, size):
                yield pb.DescribeRequest(points=pb.PointChunk(xyz=data))
        return stub.Describe(requests(), timeout=TIMEOUT)

    first, second = describe(7), describe(1000)
    one = stub.DescribeCloud(pb.DescribeCloudRequest(
        header=pb.DescribeHeader(descriptor_spec="rphsd:bins=30"),
        points=pb.PointChunk(xyz=points.tobytes())), timeout=TIMEOUT)
    assert first.descriptor_spec == "rphsd:refs=cubic27,bins=30,variant=complete"
    assert first.num_points == 1000 and len(first.values) == 81
    assert list(first.values) == list(second.values) == list(one.values)


def test_classify_stream_and_one_message_agree(stub, wire_gallery):
    points = shape(0, 9, 2000)
    streamed = stub.Classify(classify_requests(wire_gallery, points, chunk=300), timeout=TIMEOUT)
    one = stub.ClassifyCloud(pb.ClassifyCloudRequest(
        header=pb.ClassifyHeader(gallery=wire_gallery, k=1, expected_points=2000),
        points=pb.PointChunk(xyz=points.tobytes())), timeout=TIMEOUT)
    assert streamed.label == one.label == "plate"
    assert [(n.sample_id, n.distance) for n in streamed.neighbors] == [
        (n.sample_id, n.distance) for n in one.neighbors]


def test_empty_chunks_are_allowed(stub, wire_gallery):
    reply = stub.Train(train_requests(wire_gallery, [("ball", 0, shape(1, 3))], empty_chunk=True),
                       timeout=TIMEOUT)
    assert len(reply.sample_ids) == 1
    stub.RemoveSamples(pb.RemoveSamplesRequest(gallery=wire_gallery, labels=["ball"]),
                       timeout=TIMEOUT)


def test_non_finite_point_names_sample_and_point_and_changes_nothing(stub, wire_gallery):
    before = stub.GetGallery(pb.GetGalleryRequest(name=wire_gallery), timeout=TIMEOUT)
    samples = [("plate", 0, shape(0, 10 + i)) for i in range(5)]
    samples[3][2][17, 1] = np.nan
    details = rpc_error(grpc.StatusCode.INVALID_ARGUMENT, stub.Train,
                        train_requests(wire_gallery, samples))
    assert "sample 3" in details and "point 17" in details
    after = stub.GetGallery(pb.GetGalleryRequest(name=wire_gallery), timeout=TIMEOUT)
    assert (after.sample_count, after.version) == (before.sample_count, before.version)


def test_malformed_streams(stub, wire_gallery):
    odd = iter([pb.ClassifyRequest(header=pb.ClassifyHeader(gallery=wire_gallery)),
                pb.ClassifyRequest(points=pb.PointChunk(xyz=b"\0" * 13))])
    rpc_error(grpc.StatusCode.INVALID_ARGUMENT, stub.Classify, odd)
    headless = iter([pb.ClassifyRequest(points=pb.PointChunk(xyz=b"\0" * 12))])
    assert "first message must be a ClassifyHeader" in rpc_error(
        grpc.StatusCode.INVALID_ARGUMENT, stub.Classify, headless)
    two_points = np.zeros((2, 3), np.float32)
    assert "cloud has 2 points" in rpc_error(
        grpc.StatusCode.INVALID_ARGUMENT, stub.Classify,
        classify_requests(wire_gallery, two_points))
    short = iter([pb.ClassifyRequest(header=pb.ClassifyHeader(gallery=wire_gallery,
                                                              expected_points=100)),
                  pb.ClassifyRequest(points=pb.PointChunk(xyz=shape(0, 1, 50).tobytes()))])
    rpc_error(grpc.StatusCode.INVALID_ARGUMENT, stub.Classify, short)


def test_health_by_hand_encoded_messages(server):
    # What a client without grpc_health stubs (Debian's python3-grpcio has none) does:
    # HealthCheckRequest{service: ""} is no bytes; SERVING (1) is field 1, varint 1.
    with grpc.insecure_channel(server.address) as channel:
        check = channel.unary_unary("/grpc.health.v1.Health/Check",
                                    request_serializer=lambda _: b"",
                                    response_deserializer=lambda b: b)
        assert check(None, timeout=TIMEOUT) == b"\x08\x01"


# ---------------------------------------------------------------------------------------------
# Issue 39: a sensor's bytes are never silently misread. The layouts a PointCloud2 would
# declare, sent as they are: each refused with INVALID_ARGUMENT and its reason (the package
# refuses the same messages before sending: test_clouds.py, test_client.py).

SENSOR = shape(0, 7, 48)
XYZ32, XYZ64 = (0, 4, 8), (0, 8, 16)


def sensor_records(step, offsets, kind, big_endian=False, points=SENSOR):
    return records(points, (step,) + tuple((n, o, kind) for n, o in zip("xyz", offsets)),
                   big_endian)


def sensor_layout(step, offsets, datatype, big_endian=False, drop=False, width=0, row_step=0):
    x, y, z = (pb.PointCoordinate(offset=o, datatype=datatype) for o in offsets)
    return pb.PointLayout(point_step=step, x=x, y=y, z=z, is_bigendian=big_endian,
                          drop_nonfinite=drop, width=width, row_step=row_step)


def describe_sensor(stub, layout, data, expected=48, frame=None, timeout=TIMEOUT):
    return stub.DescribeCloud(pb.DescribeCloudRequest(
        header=pb.DescribeHeader(layout=layout, expected_points=expected, sensor_frame=frame),
        points=pb.PointChunk(xyz=data)), timeout=timeout)


def test_a_sensor_layout_declared_right_is_read(stub):
    reference = describe_sensor(stub, None, SENSOR.tobytes())
    for layout, data in [
            (sensor_layout(16, XYZ32, pb.FLOAT32, True), sensor_records(16, XYZ32, "f4", True)),
            (sensor_layout(32, XYZ64, pb.FLOAT64), sensor_records(32, XYZ64, "f8")),
            (sensor_layout(16, XYZ32, pb.FLOAT32, width=8, row_step=8 * 16 + 15),
             b"".join(sensor_records(16, XYZ32, "f4", points=SENSOR[r * 8:r * 8 + 8]) + b"\0" * 15
                      for r in range(6)))]:
        assert describe_sensor(stub, layout, data).values == reference.values


# (layout, data, expected_points, the message's pattern)
MIS_DECLARED = [
    # 16-byte x y z intensity declared point_step=12 (its rows then padded by 4 bytes a point)
    (sensor_layout(12, XYZ32, pb.FLOAT32, width=48, row_step=48 * 16),
     sensor_records(16, XYZ32, "f4"), 48,
     r"^point layout: row_step 768 leaves 192 bytes after width 48 x point_step 12, room for 16 "
     r"more points; rows pad by less than one point \(is point_step right\?\)$"),
    # 32-byte points declared point_step=16, row_step the data's length
    (sensor_layout(16, XYZ32, pb.FLOAT32, width=48, row_step=48 * 32),
     sensor_records(32, XYZ32, "f4"), 48, r"room for 48 more points"),
    # an organized cloud whose last row lacks its padding, or is announced in part
    (sensor_layout(16, XYZ32, pb.FLOAT32, width=8, row_step=8 * 16 + 4),
     b"".join(sensor_records(16, XYZ32, "f4", points=SENSOR[r * 8:r * 8 + 8]) + b"\0" * 4
              for r in range(6))[:-4], 0,
     r"^the points ended inside a row: 128 of its 132 bytes \(row_step\) arrived; an organized "
     r"cloud \(width 8\) is whole rows, padding included$"),
    (sensor_layout(16, XYZ32, pb.FLOAT32, width=5, row_step=5 * 16),
     sensor_records(16, XYZ32, "f4"), 48, r"^the cloud announces 48 points, not whole rows of "
                                          r"width 5"),
    # a wrong is_bigendian, dropping non-finite points or not
    (sensor_layout(16, XYZ32, pb.FLOAT32, True), sensor_records(16, XYZ32, "f4"), 48,
     r"^point layout: the points look byte-swapped: \d+ of 144 coordinates are implausible \(not "
     r"0 and outside \[2\^-40, 2\^40\]\) as declared \(is_bigendian true\), 0 read "
     r"little-endian; is is_bigendian right\?$"),
    (sensor_layout(16, XYZ32, pb.FLOAT32, True, drop=True), sensor_records(16, XYZ32, "f4"), 48,
     r"look byte-swapped"),
    (sensor_layout(32, XYZ64, pb.FLOAT64), sensor_records(32, XYZ64, "f8", True), 48,
     r"look byte-swapped: .*is_bigendian false"),
    # FLOAT64 declared over float32 data, and the reverse
    (sensor_layout(32, XYZ64, pb.FLOAT64), sensor_records(32, XYZ64, "f4"), 48,
     r"^point layout: the points look like FLOAT32 data declared FLOAT64: 144 of 144 "
     r"coordinates are implausible"),
    (sensor_layout(32, XYZ64, pb.FLOAT32), sensor_records(32, XYZ64, "f8"), 48,
     r"^point layout: the points look like FLOAT64 data declared FLOAT32: "),
]


@pytest.mark.parametrize("case", range(len(MIS_DECLARED)))
def test_a_mis_declared_sensor_layout_is_invalid_argument(stub, case):
    layout, data, expected, message = MIS_DECLARED[case]
    with pytest.raises(grpc.RpcError) as caught:
        describe_sensor(stub, layout, data, expected)
    assert caught.value.code() == grpc.StatusCode.INVALID_ARGUMENT, caught.value.details()
    assert re.search(message, caught.value.details()), caught.value.details()


def test_float64_coordinates_float32_cannot_hold_are_invalid_argument(stub):
    points = SENSOR.astype(np.float64)
    points[5, 1] = 1e-300
    layout = sensor_layout(32, XYZ64, pb.FLOAT64, drop=True)
    details = rpc_error(grpc.StatusCode.INVALID_ARGUMENT, describe_sensor, stub, layout,
                        sensor_records(32, XYZ64, "f8", points=points))
    assert details == ("point 5: y = 1e-300 (FLOAT64) is not 0 but below float32's smallest "
                       "normal (1.17549e-38): float32 data declared FLOAT64 reads like this; is "
                       "the datatype right?")
    points[5, 1], points[7, 0] = 0, -1e39  # dropped as infinite before: now refused
    details = rpc_error(grpc.StatusCode.INVALID_ARGUMENT, describe_sensor, stub, layout,
                        sensor_records(32, XYZ64, "f8", points=points))
    assert details.startswith("point 7: x = -1e+39 (FLOAT64) does not fit in a float32")


def test_a_transform_infinite_in_float32_is_named(stub):
    frame = pb.SensorFrame(transform=[1, 0, 0, 1e39, 0, 1, 0, 0, 0, 0, 1, 0])
    details = rpc_error(grpc.StatusCode.INVALID_ARGUMENT, describe_sensor, stub, None,
                        SENSOR.tobytes(), 48, frame)
    assert details == ("sensor transform: row 0 column 3 (transform[3]) is 1e+39, beyond "
                       "float32's range (|value| <= 3.40282e+38); the points are moved in float32")
