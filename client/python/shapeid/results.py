"""What the calls return: dataclasses (with __slots__, cheap to build on every call) made from
the server's response messages. Every field means what the proto's field of the same name means
(proto/shapeid/v1/shapeid.proto); durations are float seconds, times are aware UTC
datetimes, descriptors are numpy float32 arrays.
"""

import dataclasses
import datetime
from typing import Dict, List, Optional

import numpy as np

__all__ = [
    "Neighbor", "Vote", "ClassifyResult", "OrientedBox", "SceneObject", "ScenePlane",
    "SceneResult", "DescribeResult", "TrainResult", "Augmentation",
    "Gallery", "GalleryHead", "RemoveResult", "DescriptorParameter", "DescriptorKind", "MethodStats",
    "WorkLaneStats", "GalleryStats", "ServerStats", "Health", "LogLevel",
]

WEIGHTINGS = {"uniform": 1, "distance": 2}
SCALINGS = {"none": 1, "zscore": 2, "maxabs": 3}
VIEW_MIXES = {"camera": 1, "varied": 2}


def _name(table, value):
    for name, number in table.items():
        if number == value:
            return name
    return "unspecified"


def _seconds(duration):
    return duration.seconds + duration.nanos / 1e9


def _time(timestamp):
    if timestamp.seconds == 0 and timestamp.nanos == 0:
        return None
    return datetime.datetime.fromtimestamp(timestamp.seconds + timestamp.nanos / 1e9,
                                           datetime.timezone.utc)


@dataclasses.dataclass(slots=True)
class Neighbor:
    sample_id: int
    label: str
    distance: float  # between descriptors, in the gallery's scaled feature space
    view: int = 0    # 0: the trained cloud; i >= 1: its i-th synthetic view
    source: str = ""  # where the sample came from, as trained ("" when not given)
    metadata: Dict[str, str] = dataclasses.field(default_factory=dict)


@dataclasses.dataclass(slots=True)
class Sample:
    """One trained sample as Client.list_samples gives it: everything but its descriptors."""
    sample_id: int
    label: str
    views: int   # descriptors stored: 1, or 1 + synthetic views (augmented galleries)
    source: str  # "" when not given
    metadata: Dict[str, str]

    @classmethod
    def from_proto(cls, s):
        return cls(s.sample_id, s.label, s.views, s.source, dict(s.metadata))


@dataclasses.dataclass(slots=True)
class Vote:
    label: str
    weight: float


@dataclasses.dataclass(slots=True)
class ClassifyResult:
    label: str                 # the winner, or "unknown" beyond the reject distance
    unknown: bool
    confidence: float          # the winner's share of the vote, (0, 1]; 0 when unknown
    neighbors: List[Neighbor]  # nearest first
    votes: List[Vote]          # most weight first
    num_points: int            # points the server received
    describe_seconds: float
    search_seconds: float
    approximate: bool          # the search read the approximate index
    by_head: bool = False      # the gallery's trained head answered with the vote

    @classmethod
    def from_proto(cls, r):
        return cls(label=r.label, unknown=r.unknown, confidence=r.confidence,
                   neighbors=[Neighbor(n.sample_id, n.label, n.distance, n.view, n.source,
                                       dict(n.metadata))
                              for n in r.neighbors],
                   votes=[Vote(v.label, v.weight) for v in r.votes],
                   num_points=r.num_points, describe_seconds=_seconds(r.describe_time),
                   search_seconds=_seconds(r.search_time), approximate=r.approximate,
                   by_head=r.by_head)


def _vector(v):
    return np.array([v.x, v.y, v.z])


@dataclasses.dataclass(slots=True, eq=False)  # numpy fields: compare them with numpy
class OrientedBox:
    """vision_msgs/BoundingBox3D's box, in the frame's coordinates: the rotation takes the
    frame's axes onto the points' principal axes (x along the largest spread, then y, then
    z; right-handed); size is the full extents along them."""
    center: np.ndarray       # (3,) float64
    orientation: np.ndarray  # (4,) float64, a unit quaternion x, y, z, w
    size: np.ndarray         # (3,) float64

    @classmethod
    def from_proto(cls, b):
        q = b.orientation
        return cls(center=_vector(b.center), orientation=np.array([q.x, q.y, q.z, q.w]),
                   size=_vector(b.size))


@dataclasses.dataclass(slots=True, eq=False)
class SceneObject:
    """One object of a frame: the gallery's answer for its points, as classify gives it, and
    where it is, in the frame's coordinates."""
    classification: ClassifyResult  # label or "unknown"; num_points is the object's
    centroid: np.ndarray            # (3,) float64, the mean of its points
    box: OrientedBox
    indices: Optional[np.ndarray]   # uint32, ascending, into the frame as sent; None unless
                                    # return_indices
    error: str                      # why it could not be described ("": it was)

    @property
    def label(self):
        return self.classification.label

    @property
    def num_points(self):
        return self.classification.num_points

    @classmethod
    def from_proto(cls, o, with_indices):
        return cls(classification=ClassifyResult.from_proto(o.classification),
                   centroid=_vector(o.centroid), box=OrientedBox.from_proto(o.box),
                   indices=np.array(o.indices, np.uint32) if with_indices else None,
                   error=o.error)


@dataclasses.dataclass(slots=True, eq=False)
class ScenePlane:
    """A support removed: a x + b y + c z + d = 0, (a, b, c) a unit normal pointing up with a
    sensor frame, else towards the sensor (d >= 0)."""
    coefficients: np.ndarray  # (4,) float64: a, b, c, d
    num_points: int


@dataclasses.dataclass(slots=True, eq=False)
class SceneResult:
    """Client.recognize_scene's answer. Every point sent is in exactly one of the planes, the
    objects or the counts non_finite_points, outside_region, in_small_clusters and
    in_large_clusters."""
    objects: List[SceneObject]  # largest first
    planes: List[ScenePlane]    # in the order removed, largest first
    num_points: int             # points sent
    non_finite_points: int      # skipped
    outside_region: int
    in_small_clusters: int      # fewer than min_cluster_points: noise
    in_large_clusters: int      # more than max_cluster_points: background
    segment_seconds: float
    classify_seconds: float     # all objects

    @classmethod
    def from_proto(cls, r, with_indices):
        return cls(objects=[SceneObject.from_proto(o, with_indices) for o in r.objects],
                   planes=[ScenePlane(np.array(p.coefficients, np.float64), p.num_points)
                           for p in r.planes],
                   num_points=r.num_points, non_finite_points=r.non_finite_points,
                   outside_region=r.outside_region, in_small_clusters=r.in_small_clusters,
                   in_large_clusters=r.in_large_clusters,
                   segment_seconds=_seconds(r.segment_time),
                   classify_seconds=_seconds(r.classify_time))


@dataclasses.dataclass(slots=True, eq=False)  # compare .values with numpy, not ==
class DescribeResult:
    descriptor_spec: str  # canonical: equal specs give equal vectors
    values: np.ndarray    # float32, exactly as the server computed them
    num_points: int
    describe_seconds: float

    @classmethod
    def from_proto(cls, r):
        return cls(descriptor_spec=r.descriptor_spec, values=np.array(r.values, np.float32),
                   num_points=r.num_points, describe_seconds=_seconds(r.describe_time))


@dataclasses.dataclass(slots=True)
class TrainResult:
    sample_ids: List[int]  # in the order of the clouds given, server-assigned ones included
    gallery_sample_count: int
    gallery_version: int
    describe_seconds: float  # over all the samples

    @classmethod
    def from_proto(cls, r):
        return cls(sample_ids=list(r.sample_ids), gallery_sample_count=r.gallery_sample_count,
                   gallery_version=r.gallery_version, describe_seconds=_seconds(r.describe_time))


@dataclasses.dataclass(slots=True)
class Augmentation:
    """Training-time view augmentation (proto ViewAugmentation): each trained cloud also
    becomes `views` synthetic single-view scans. Zeros and None take the server's defaults."""
    views: int = 0              # 0 to 64; 0: off
    noise: Optional[float] = None  # fraction of the object's extent; None: 0.01
    min_points: int = 0         # 0: 300
    max_points: int = 0         # 0: 500
    random_pose: bool = False
    seed: int = 0               # 0: 1
    # "camera" (a depth camera's visible side) or "varied" (camera, plane cuts and occluded
    # cameras in turn, noise drawn in [0, 2 x noise]); None: the server's, "camera".
    mix: Optional[str] = None

    def to_proto(self, message):
        message.views = self.views
        if self.noise is not None:
            message.noise = self.noise
        message.min_points = self.min_points
        message.max_points = self.max_points
        message.random_pose = self.random_pose
        message.seed = self.seed
        if self.mix is not None:
            if self.mix not in VIEW_MIXES:
                raise ValueError(f"augmentation mix {self.mix!r}: expected one of "
                                 f"{', '.join(VIEW_MIXES)}")
            message.mix = VIEW_MIXES[self.mix]

    @classmethod
    def from_proto(cls, a):
        return cls(views=a.views, noise=a.noise if a.HasField("noise") else None,
                   min_points=a.min_points, max_points=a.max_points, random_pose=a.random_pose,
                   seed=a.seed, mix=_name(VIEW_MIXES, a.mix) if a.mix else "camera")


@dataclasses.dataclass(slots=True)
class Gallery:
    name: str
    descriptor_spec: str  # canonical
    dimension: int
    k: int
    weighting: str        # "uniform" or "distance"
    scaling: str          # "none", "zscore" or "maxabs"
    reject_distance: float
    sample_count: int
    label_counts: Dict[str, int]  # sorted by label
    create_time: Optional[datetime.datetime]
    update_time: Optional[datetime.datetime]
    version: int
    descriptor_version: int
    software_version: str
    incompatible: str     # empty, or why this server cannot train or classify it
    augmentation: Augmentation
    vector_count: int
    approximate_lists: int  # 0: exact search
    head: Optional["GalleryHead"] = None  # the trained head, once the server has fitted one

    @classmethod
    def from_proto(cls, g):
        return cls(name=g.name, descriptor_spec=g.descriptor_spec, dimension=g.dimension,
                   k=g.knn.k, weighting=_name(WEIGHTINGS, g.knn.weighting),
                   scaling=_name(SCALINGS, g.knn.scaling), reject_distance=g.reject_distance,
                   sample_count=g.sample_count,
                   label_counts={c.label: c.count for c in g.label_counts},
                   create_time=_time(g.create_time), update_time=_time(g.update_time),
                   version=g.version, descriptor_version=g.descriptor_version,
                   software_version=g.software_version, incompatible=g.incompatible,
                   augmentation=Augmentation.from_proto(g.augmentation),
                   vector_count=g.vector_count, approximate_lists=g.approximate_lists,
                   head=GalleryHead.from_proto(g.head) if g.HasField("head") else None)


@dataclasses.dataclass(slots=True)
class GalleryHead:
    fitted_version: int     # the gallery version it was fitted on
    answers: bool           # its labels are the gallery's: it answers Classify with the vote
    fitted_samples: int
    fitted_vectors: int
    holdout_samples: int    # held out of the fit (about one in ten) ...
    holdout_vectors: int
    holdout_accuracy: float  # ... and the share of their vectors it got right
    fit_seconds: float

    @classmethod
    def from_proto(cls, h):
        return cls(fitted_version=h.fitted_version, answers=h.answers,
                   fitted_samples=h.fitted_samples, fitted_vectors=h.fitted_vectors,
                   holdout_samples=h.holdout_samples, holdout_vectors=h.holdout_vectors,
                   holdout_accuracy=h.holdout_accuracy, fit_seconds=_seconds(h.fit_time))


@dataclasses.dataclass(slots=True)
class RemoveResult:
    removed: int
    remaining: int


@dataclasses.dataclass(slots=True)
class DescriptorParameter:
    name: str
    default_value: str
    help: str


@dataclasses.dataclass(slots=True)
class DescriptorKind:
    kind: str
    summary: str
    parameters: List[DescriptorParameter]
    default_spec: str
    default_dimension: int

    @classmethod
    def from_proto(cls, d):
        return cls(kind=d.kind, summary=d.summary,
                   parameters=[DescriptorParameter(p.name, p.default_value, p.help)
                               for p in d.parameters],
                   default_spec=d.default_spec, default_dimension=d.default_dimension)


@dataclasses.dataclass(slots=True)
class MethodStats:
    method: str
    calls: int
    errors: int
    latency_p50_seconds: Optional[float]  # None when there were no calls
    latency_p99_seconds: Optional[float]
    wait_p50_seconds: Optional[float]     # None when no call queued work
    wait_p99_seconds: Optional[float]


@dataclasses.dataclass(slots=True)
class WorkLaneStats:
    lane: str  # "cheap", "heavy" or "store"
    workers: int
    running: int
    queued: int


@dataclasses.dataclass(slots=True)
class GalleryStats:
    name: str
    samples: int
    version: int


@dataclasses.dataclass(slots=True)
class ServerStats:
    version: str
    uptime_seconds: float
    state: str  # "serving", "loading", "store unreachable" or "draining"
    calls_in_flight: int
    methods: List[MethodStats]
    galleries: List[GalleryStats]  # largest first
    samples: int
    points_received: int
    resident_memory_bytes: int
    store: str
    log_level: str
    metrics_address: str
    work: List[WorkLaneStats]
    memory_budget_bytes: int
    memory_held_bytes: int
    memory_held_peak_bytes: int

    @classmethod
    def from_proto(cls, s):
        def optional(message, field):
            return _seconds(getattr(message, field)) if message.HasField(field) else None
        return cls(
            version=s.version, uptime_seconds=_seconds(s.uptime), state=s.state,
            calls_in_flight=s.calls_in_flight,
            methods=[MethodStats(m.method, m.calls, m.errors, optional(m, "latency_p50"),
                                 optional(m, "latency_p99"), optional(m, "wait_p50"),
                                 optional(m, "wait_p99")) for m in s.methods],
            galleries=[GalleryStats(g.name, g.samples, g.version) for g in s.galleries],
            samples=s.samples, points_received=s.points_received,
            resident_memory_bytes=s.resident_memory_bytes, store=s.store,
            log_level=s.log_level, metrics_address=s.metrics_address,
            work=[WorkLaneStats(w.lane, w.workers, w.running, w.queued) for w in s.work],
            memory_budget_bytes=s.memory_budget_bytes, memory_held_bytes=s.memory_held_bytes,
            memory_held_peak_bytes=s.memory_held_peak_bytes)


@dataclasses.dataclass(slots=True)
class Health:
    """grpc.health.v1 status of the whole server: "SERVING", "NOT_SERVING" (loading its
    galleries or shutting down), "UNKNOWN" or "SERVICE_UNKNOWN"."""
    status: str

    @property
    def serving(self):
        return self.status == "SERVING"


@dataclasses.dataclass(slots=True)
class LogLevel:
    previous_level: str
    level: str
