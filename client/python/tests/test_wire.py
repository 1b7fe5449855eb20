"""The wire contract, through the generated stubs alone (shapeid.v1): what any gRPC client
written from proto/shapeid/v1/shapeid.proto may send, including what the shapeid.Client
never sends (malformed streams, non-finite points, odd chunkings), answered with the proto's
status codes. Formerly tests/python/interop_test.py (issue 3); its calls that the package
makes the ordinary way are tested through the package in test_client.py."""

import grpc
import numpy as np
import pytest

from conftest import shape
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
