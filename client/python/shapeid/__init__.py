"""shapeid: recognize 3D objects from point clouds with a shapeid server.

    import shapeid
    client = shapeid.Client("127.0.0.1:50051")
    client.create_gallery("lab")
    client.train("lab", [mug, box], ["mug", "box"])   # N x 3 arrays, Open3D clouds, PointCloud2
    print(client.classify("lab", scan).label)

docs/python.md has the rest: what clouds are accepted and how they convert, errors,
deadlines, retries, API keys, TLS and threads. The generated protobuf messages are in
shapeid.v1 (shapeid_pb2, shapeid_pb2_grpc), for those who want the wire itself.
"""

from ._channel import DEFAULT_PORT, MAX_RECEIVE_BYTES
from .client import Client
from .clouds import encode
from .errors import (AbortedError, AlreadyExistsError, CancelledError, DataLossError,
                     DeadlineExceededError, FailedPreconditionError, InvalidArgumentError,
                     NotFoundError, PermissionDeniedError, ResourceExhaustedError,
                     ShapeidError, UnauthenticatedError, UnavailableError, UnimplementedError)
from .results import (Augmentation, ClassifyResult, DescribeResult, DescriptorKind,
                      DescriptorParameter, Gallery, GalleryHead, GalleryStats, Health, LogLevel, MethodStats,
                      Neighbor, OrientedBox, RemoveResult, Sample, SceneObject, ScenePlane,
                      SceneResult, ServerStats, TrainResult, Vote, WorkLaneStats)

__version__ = "0.1.0"
