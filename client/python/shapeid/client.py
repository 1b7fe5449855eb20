"""The Python client of a shapeid server: the calls of the C++ client (client/client.h), with
the same deadlines, retries, API keys, TLS and chunking."""

import time

import grpc
import numpy as np

from . import clouds as _clouds
from . import gallery_file as _gallery_file
from . import results as _results
from ._channel import MAX_RECEIVE_BYTES
from ._channel import make_channel as _make_channel
from .errors import ShapeidError, error_for, from_rpc_error

try:
    from .v1 import shapeid_pb2 as _pb
    from .v1 import shapeid_pb2_grpc as _pb_grpc
except ImportError as e:  # a source checkout: the stubs are made when the package is built
    raise ImportError(
        "shapeid: the generated stubs (shapeid/v1/shapeid_pb2*.py) are missing (%s). Install "
        "the package (pip install --no-build-isolation client/python, docs/python.md), which "
        "generates them from proto/ with protoc and grpc_python_plugin." % e) from e

__all__ = ["Client"]

_RETRIED = (grpc.StatusCode.UNAVAILABLE, grpc.StatusCode.CANCELLED)
_HEALTH_STATUSES = {0: "UNKNOWN", 1: "SERVING", 2: "NOT_SERVING", 3: "SERVICE_UNKNOWN"}
_REQUEST_ID_CHARS = frozenset(
    "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789._:/+=-")
# core/request_id.h's IsValidCallerId.
_CALLER_ID_CHARS = frozenset(
    "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789._:-")


class Client:
    """A connection to a shapeid server (or a set of replicas).

        client = shapeid.Client("127.0.0.1:50051")
        client.create_gallery("lab")
        client.train("lab", [mug_points, box_points], ["mug", "box"])
        print(client.classify("lab", scan).label)

    A cloud is an N x 3 numpy array of floats, an open3d.geometry.PointCloud or a ROS
    PointCloud2 message (shapeid.clouds says exactly what is accepted and how it converts).

    Every call has a deadline: `timeout` seconds when given, else the client's `deadline`
    (30 s), retries and backoff included. Calls that are safe to repeat are retried up to
    `max_attempts` times while the server answers UNAVAILABLE or CANCELLED (a replica that
    is down, loading or shutting down), after `initial_backoff` seconds, doubled each time;
    never on RESOURCE_EXHAUSTED. Errors raise a ShapeidError subclass carrying the gRPC code
    and the server's message.

    Thread safety: a Client may be shared by any number of threads; it holds no per-call
    state. Close it (or use it as a context manager) to release its connections.
    """

    def __init__(self, target="127.0.0.1:50051", *, deadline=30.0, max_attempts=3,
                 initial_backoff=0.1, chunk_points=16384, load_balancing="round_robin",
                 api_key=None, request_id=None, caller_id=None, tls=False, tls_ca_file=None,
                 tls_cert_file=None, tls_key_file=None, tls_server_name=None,
                 max_receive_bytes=MAX_RECEIVE_BYTES):
        """Checks the options (ValueError naming the bad one) and opens the channel. Touches
        the network only to look up the host names of a list of replicas; a server that is
        down, or a TLS handshake that fails, shows as UnavailableError on the first call.

        target: "HOST:PORT", "dns:///NAME:PORT" (every address a replica), "unix:///PATH",
          or a list "HOST:PORT,HOST:PORT" of replicas (looked up once), as ClientOptions
          (client/client_options.h) says.
        load_balancing: "round_robin" (calls spread over the replicas that serve) or
          "pick_first" (one replica until it breaks).
        api_key: sent with every call as "authorization: Bearer KEY". Use TLS on a network.
        request_id: sent with every call as "x-request-id" (1 to 128 of A-Z a-z 0-9 ._:/+=-)
          so the server's logs find every call of a job.
        caller_id: sent with every call as "shapeid-caller-id" (1 to 64 of A-Z a-z 0-9 ._:-):
          on a server without API keys this client is then a caller of its own for the
          server's fair shares, not one with every process of its host (one id per robot of
          a fleet on one machine). With an api_key it changes nothing: the key is the caller.
        tls: turn TLS on (it is also on when any tls_* file is given). tls_ca_file: PEM of
          the CAs that may sign the server's certificate (None: the system's roots).
          tls_cert_file and tls_key_file: this client's certificate and key, for mutual TLS
          (both or neither). tls_server_name: the name the server's certificate must carry
          when it is not the target's host.
        chunk_points: points per PointChunk message; a cloud of at most this many points
          travels in one DescribeCloud / ClassifyCloud message.
        max_receive_bytes: the largest answer this client reads (default MAX_RECEIVE_BYTES,
          256 MiB: any answer a shapeid server sends). A larger one raises
          ResourceExhaustedError with client_limit True: this client's refusal, not the
          server's.
        """
        if not target:
            raise ValueError("target is empty")
        if not isinstance(max_attempts, int) or max_attempts < 1:
            raise ValueError("max_attempts must be an integer >= 1, got %r" % (max_attempts,))
        if not isinstance(chunk_points, int) or chunk_points < 1:
            raise ValueError("chunk_points must be an integer >= 1, got %r" % (chunk_points,))
        if not deadline or deadline <= 0:
            raise ValueError("deadline must be positive (seconds), got %r" % (deadline,))
        if (not isinstance(max_receive_bytes, int) or
                not 1 <= max_receive_bytes <= 2**31 - 1):
            raise ValueError("max_receive_bytes must be an integer from 1 to 2^31 - 1, got %r"
                             % (max_receive_bytes,))
        if initial_backoff < 0:
            raise ValueError("initial_backoff must be >= 0, got %r" % (initial_backoff,))
        metadata = []
        if api_key:
            if any(c <= " " or c == "\x7f" or not c.isascii() for c in api_key):
                raise ValueError("the API key holds a space, a line break or another character "
                                 "metadata cannot carry (a stray newline from a file?)")
            metadata.append(("authorization", "Bearer " + api_key))
        if request_id:
            if len(request_id) > 128 or not set(request_id) <= _REQUEST_ID_CHARS:
                raise ValueError("request id %r: a request id is 1 to 128 characters of A-Z a-z "
                                 "0-9 . _ : / + = -" % (request_id,))
            metadata.append(("x-request-id", request_id))
        if caller_id:
            if len(caller_id) > 64 or not set(caller_id) <= _CALLER_ID_CHARS:
                raise ValueError("caller id %r: a caller id is 1 to 64 characters of A-Z a-z 0-9 "
                                 ". _ : -" % (caller_id,))
            metadata.append(("shapeid-caller-id", caller_id))
        self._target = target
        self._deadline = float(deadline)
        self._max_attempts = max_attempts
        self._initial_backoff = float(initial_backoff)
        self._chunk_points = chunk_points
        self._metadata = tuple(metadata)
        self._max_receive_bytes = max_receive_bytes
        self._channel = _make_channel(target, load_balancing, tls, tls_ca_file, tls_cert_file,
                                      tls_key_file, tls_server_name, max_receive_bytes)
        self._stub = _pb_grpc.ShapeIdStub(self._channel)
        self._health_check = self._channel.unary_unary(
            "/grpc.health.v1.Health/Check", request_serializer=_identity,
            response_deserializer=_identity)
        # Set once a server answers UNIMPLEMENTED to DescribeCloud / ClassifyCloud (an older
        # release): stream from then on. Written only from False to True.
        self._server_lacks_one_message_calls = False

    @property
    def target(self):
        return self._target

    def close(self):
        """Closes the channel; calls after this fail."""
        self._channel.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __repr__(self):
        return "shapeid.Client(%r)" % self._target

    # -----------------------------------------------------------------------------------------
    # Clouds

    def describe(self, cloud, *, spec="", gallery="", drop_non_finite=False, up=None,
                 transform=None, timeout=None):
        """The descriptor of `cloud` as a DescribeResult (values: numpy float32). `spec` empty:
        the spec of `gallery` if given, else the server's default ("dfsd"). `up` or
        `transform`: the sensor's frame (see classify)."""
        frame = _sensor_frame(up, transform)
        encoded = _clouds.encode(cloud, drop_non_finite=drop_non_finite)
        header = _pb.DescribeHeader(descriptor_spec=spec, gallery=gallery,
                                    expected_points=encoded.num_points)
        _set_format(header, encoded, drop_non_finite, frame)
        response = self._cloud_call(header, encoded, _pb.DescribeCloudRequest,
                                    _pb.DescribeRequest, self._stub.DescribeCloud,
                                    self._stub.Describe, timeout)
        return _results.DescribeResult.from_proto(response)

    def classify(self, gallery, cloud, *, k=0, exact=False, drop_non_finite=False, up=None,
                 transform=None, timeout=None):
        """Classifies `cloud` against `gallery` with `k` neighbors (0: the gallery's k) as a
        ClassifyResult. NotFoundError for an unknown gallery, FailedPreconditionError for an
        empty one. exact=True searches every stored vector even where the server searches
        the gallery approximately.

        The sensor's frame, at most one of (both: ValueError); neither: the points are in
        the gallery's frame already. The server moves the points before describing them.
        up: (x, y, z), which way is up in the sensor's frame; the points are turned by the
          smallest rotation taking it onto the gallery's up (its descriptor's, +z unless the
          spec says otherwise). A camera's optical frame (y down): up=(0, -1, 0).
        transform: the sensor-to-gallery rigid transform [R | t] (p' = R p + t), 3 x 4 or
          4 x 4 (last row 0 0 0 1), array-like: a tf lookup as a matrix. A transform that
          is not rigid is the server's InvalidArgumentError."""
        frame = _sensor_frame(up, transform)
        encoded = _clouds.encode(cloud, drop_non_finite=drop_non_finite)
        header = _pb.ClassifyHeader(gallery=gallery, k=k, exact=exact,
                                    expected_points=encoded.num_points)
        _set_format(header, encoded, drop_non_finite, frame)
        response = self._cloud_call(header, encoded, _pb.ClassifyCloudRequest,
                                    _pb.ClassifyRequest, self._stub.ClassifyCloud,
                                    self._stub.Classify, timeout)
        return _results.ClassifyResult.from_proto(response)

    def recognize_scene(self, gallery, cloud, *, k=0, exact=False, up=None, transform=None,
                        max_planes=None, plane_distance=None, min_plane_share=None,
                        plane_iterations=None, cluster_tolerance=None, min_cluster_points=None,
                        max_cluster_points=None, max_plane_tilt_degrees=None, region=None,
                        seed=0, return_indices=False, timeout=None):
        """Finds the objects in one sensor frame (a depth camera's or LiDAR's cloud of a table
        or floor with things on it) and classifies each against `gallery` as a SceneResult:
        the supporting planes are removed, the rest split into clusters, each cluster
        classified with `k` neighbors (0: the gallery's k) as classify would. Distances are
        in the frame's units (the defaults assume metres); every answer (centroids, boxes,
        planes) is in the frame's coordinates.

        Non-finite points (a depth camera's missing returns) are sent, never refused nor
        dropped here: the server skips and counts them (non_finite_points), so that indices
        count every point of the frame, an organized PointCloud2's index being its pixel
        (row * width + column).

        up, transform: the sensor's frame, as in classify: each object is moved by it before
          it is described, and only planes within max_plane_tilt_degrees of level are
          supports. Neither: the first plane removed gives up.
        Segmentation (proto SceneSegmentation; None: the server's default, so that 0 is
        never mistaken for one): max_planes (0 to 16, 1), plane_distance (0.01),
        min_plane_share (0.05), plane_iterations (1,000), cluster_tolerance (0.02),
        min_cluster_points (100), max_cluster_points (1,000,000), max_plane_tilt_degrees
        (15). A value out of range is the server's InvalidArgumentError naming it.
        region: ((min x, y, z), (max x, y, z)), a 2 x 3 array-like: only points inside are
          considered. seed: seeds RANSAC (the same frame and seed, the same answer).
        return_indices: fill each object's `indices` (numpy uint32, ascending), to color or
          crop the frame; else they are None.
        NotFoundError for an unknown gallery, FailedPreconditionError for an empty one."""
        frame = _sensor_frame(up, transform)
        encoded = _clouds.encode(cloud, keep_non_finite=True)
        header = _pb.SceneHeader(gallery=gallery, k=k, exact=exact,
                                 expected_points=encoded.num_points,
                                 return_indices=bool(return_indices))
        _set_format(header, encoded, False, frame)
        _set_optional(header.segmentation, max_planes=max_planes, plane_distance=plane_distance,
                      min_plane_share=min_plane_share, plane_iterations=plane_iterations,
                      cluster_tolerance=cluster_tolerance, min_cluster_points=min_cluster_points,
                      max_cluster_points=max_cluster_points,
                      max_plane_tilt_degrees=max_plane_tilt_degrees, seed=seed)
        if region is not None:
            box = _region(region)
            for vector, values in zip((header.region.min, header.region.max), box):
                vector.x, vector.y, vector.z = values
        response = self._cloud_call(header, encoded, _pb.RecognizeSceneCloudRequest,
                                    _pb.RecognizeSceneRequest, self._stub.RecognizeSceneCloud,
                                    self._stub.RecognizeScene, timeout,
                                    stream_if_unimplemented=False)
        return _results.SceneResult.from_proto(response, bool(return_indices))

    def train(self, gallery, clouds, labels, *, ids=None, sources=None, metadata=None,
              augmentation=None, drop_non_finite=False, up=None, transform=None, timeout=None):
        """Adds labeled clouds to `gallery` in one stream: all of them or, on any error, none.
        Returns a TrainResult (the new sample ids, in order).

        clouds: one cloud, or a sequence of clouds (a 3-D array is a batch of N x 3 clouds).
        labels: one label for every cloud, or one per cloud.
        ids: None (the server assigns ids), or one id per cloud (0: the server assigns
          that one). Retried on UNAVAILABLE only when every id is client-chosen, so a
          repeated stream cannot add a sample twice; an AlreadyExistsError after such a
          retry says that the first attempt may have committed.
        sources: None, or one string per cloud (a file path, a URI, "" for none): kept with
          the sample and returned with it as a neighbor and by list_samples, so that an
          answer can be traced to the scan it matched (at most 4,096 bytes each).
        metadata: None, one dict of str -> str for every cloud, or one dict per cloud: small
          key/value pairs kept the same way (at most 64 pairs, 4,096 bytes in all).
        augmentation: a shapeid.Augmentation for this stream instead of the gallery's.
        up, transform: the sensor's frame of every cloud of the stream (see classify).
        Every cloud is checked before anything is sent; a bad one raises TypeError or
        ValueError naming its index. The stream declares one point layout: PointCloud2
        messages of one layout go as they are, a mix of layouts (or with arrays) is
        converted to packed float32 here.
        """
        frame = _sensor_frame(up, transform)
        clouds = _as_cloud_list(clouds)
        if isinstance(labels, str):
            labels = [labels] * len(clouds)
        labels = list(labels)
        if len(labels) != len(clouds):
            raise ValueError("%d clouds but %d labels" % (len(clouds), len(labels)))
        for i, label in enumerate(labels):
            if not isinstance(label, str) or not label:
                raise ValueError("labels[%d] is %r; a label is a non-empty string" % (i, label))
        ids = [0] * len(clouds) if ids is None else [int(i) for i in ids]
        if len(ids) != len(clouds):
            raise ValueError("%d clouds but %d ids" % (len(clouds), len(ids)))
        if any(i < 0 or i >= 1 << 64 for i in ids):
            raise ValueError("sample ids are unsigned 64-bit integers (0: the server assigns)")
        sources = [""] * len(clouds) if sources is None else list(sources)
        if len(sources) != len(clouds):
            raise ValueError("%d clouds but %d sources" % (len(clouds), len(sources)))
        for i, source in enumerate(sources):
            if not isinstance(source, str):
                raise TypeError("sources[%d] is %r; a source is a string" % (i, source))
        if metadata is None or isinstance(metadata, dict):
            metadata = [metadata or {}] * len(clouds)
        metadata = list(metadata)
        if len(metadata) != len(clouds):
            raise ValueError("%d clouds but %d metadata dicts" % (len(clouds), len(metadata)))
        for i, pairs in enumerate(metadata):
            if not isinstance(pairs, dict) or not all(
                    isinstance(k, str) and isinstance(v, str) for k, v in pairs.items()):
                raise TypeError("metadata[%d] is %r; metadata is a dict of str -> str"
                                % (i, pairs))
        def encode_all(forward):
            encoded = []
            for i, cloud in enumerate(clouds):
                try:
                    encoded.append(_clouds.encode(cloud, drop_non_finite=drop_non_finite,
                                                  forward_point_cloud2=forward))
                except (TypeError, ValueError) as e:
                    raise type(e)("clouds[%d]: %s" % (i, e)) from None
            return encoded

        encoded = encode_all(True)
        if len({cloud.layout for cloud in encoded}) > 1:
            encoded = encode_all(False)  # one layout per stream: all packed float32
        header = _pb.TrainHeader(gallery=gallery)
        if encoded:
            _set_format(header, encoded[0], drop_non_finite, frame)
        elif frame is not None:
            header.sensor_frame.CopyFrom(frame)
        if augmentation is not None:
            augmentation.to_proto(header.augmentation)

        def requests():
            yield _pb.TrainRequest(header=header)
            for label, sample_id, cloud, source, pairs in zip(labels, ids, encoded, sources,
                                                              metadata):
                yield _pb.TrainRequest(sample=_pb.SampleHeader(
                    label=label, sample_id=sample_id, expected_points=cloud.num_points,
                    source=source, metadata=pairs))
                for chunk in cloud.chunks(self._chunk_points):
                    yield _pb.TrainRequest(points=_pb.PointChunk(xyz=chunk))

        attempts = []

        def attempt(remaining):
            attempts.append(None)
            return self._stub.Train(requests(), timeout=remaining, metadata=self._metadata)

        all_ids = bool(ids) and all(ids)
        try:
            response = self._call(all_ids, attempt, timeout)
        except ShapeidError as e:
            if e.code == grpc.StatusCode.ALREADY_EXISTS and len(attempts) > 1:
                raise error_for(e.code, e.message + " (an earlier attempt of this train got no "
                                "answer and may have committed these samples: check the "
                                "gallery before training them again)") from None
            raise
        return _results.TrainResult.from_proto(response)

    # -----------------------------------------------------------------------------------------
    # Galleries

    def create_gallery(self, name, *, spec="", k=0, weighting=None, scaling=None,
                       reject_distance=0.0, augmentation=None, timeout=None):
        """Creates gallery `name` and returns it (a Gallery). spec: descriptor spec ("":
        the server's default, "dfsd"); k: neighbors that vote (0: 1); weighting: "uniform"
        or "distance"; scaling: "none", "zscore" or "maxabs"; reject_distance > 0: answer
        "unknown" beyond it; augmentation: a shapeid.Augmentation. Sent once (not retried).
        AlreadyExistsError if the name is taken."""
        request = _pb.CreateGalleryRequest(name=name, descriptor_spec=spec,
                                           reject_distance=reject_distance)
        request.knn.k = k
        if weighting is not None:
            request.knn.weighting = _choice(weighting, _results.WEIGHTINGS, "weighting")
        if scaling is not None:
            request.knn.scaling = _choice(scaling, _results.SCALINGS, "scaling")
        if augmentation is not None:
            augmentation.to_proto(request.augmentation)
        response = self._unary(False, self._stub.CreateGallery, request, timeout)
        return _results.Gallery.from_proto(response)

    def get_gallery(self, name, *, timeout=None):
        """Gallery `name` (NotFoundError if there is none)."""
        request = _pb.GetGalleryRequest(name=name)
        return _results.Gallery.from_proto(
            self._unary(True, self._stub.GetGallery, request, timeout))

    def list_galleries(self, *, timeout=None):
        """Every gallery, sorted by name."""
        response = self._unary(True, self._stub.ListGalleries, _pb.ListGalleriesRequest(),
                               timeout)
        return [_results.Gallery.from_proto(g) for g in response.galleries]

    def delete_gallery(self, name, *, timeout=None):
        """Deletes gallery `name`; returns how many samples went with it. Sent once."""
        response = self._unary(False, self._stub.DeleteGallery,
                               _pb.DeleteGalleryRequest(name=name), timeout)
        return response.samples_deleted

    def remove_samples(self, gallery, *, ids=(), labels=(), timeout=None):
        """Removes the samples with any of `ids` and every sample of `labels`, all or nothing
        (an unknown id: NotFoundError). Returns a RemoveResult. Sent once."""
        if isinstance(labels, str):
            labels = [labels]
        request = _pb.RemoveSamplesRequest(gallery=gallery, sample_ids=[int(i) for i in ids],
                                           labels=list(labels))
        response = self._unary(False, self._stub.RemoveSamples, request, timeout)
        return _results.RemoveResult(response.removed, response.remaining)

    def list_samples(self, gallery, *, label="", page_size=1000, timeout=None):
        """Yields gallery `gallery`'s samples (shapeid.Sample: id, label, views, source,
        metadata) in id order, fetching a page of `page_size` (1 to 10,000) at a time, each
        page with `timeout`. Samples trained or removed while it runs appear or not as the
        gallery is when their page is read. label: only the samples of that label."""
        request = _pb.ListSamplesRequest(gallery=gallery, label=label, page_size=page_size)
        while True:
            response = self._unary(True, self._stub.ListSamples, request, timeout)
            for sample in response.samples:
                yield _results.Sample.from_proto(sample)
            if not response.next_page_token:
                return
            request.page_token = response.next_page_token

    def export_gallery(self, name, file, *, timeout=None):
        """Streams gallery `name` into `file` (a path, or a binary file object) as the
        portable gallery file of `shapeid gallery export`; returns the number of samples.
        A path only ever holds a whole export (written beside it, then renamed); on an
        error it keeps what it held. Retried only while no chunk has been written. The
        whole stream must fit the deadline: raise `timeout` for very large galleries."""
        request = _pb.ExportGalleryRequest(name=name)
        writer = _gallery_file.Writer(file)
        delivered = []
        try:
            def attempt(remaining):
                samples = 0
                for chunk in self._stub.ExportGallery(request, timeout=remaining,
                                                      metadata=self._metadata):
                    delivered.append(None)
                    writer.write(chunk.SerializeToString())
                    if chunk.HasField("trailer"):
                        samples = chunk.trailer.sample_count
                return samples

            samples = self._call(True, attempt, timeout, may_retry=lambda: not delivered)
            writer.commit()
            return samples
        finally:
            writer.close()

    def import_gallery(self, file, *, name="", timeout=None):
        """Streams a gallery file (a path or a binary file object, as export_gallery or
        `shapeid gallery export` wrote it) into the server, all or nothing, optionally under
        a new `name`; returns the new Gallery. AlreadyExistsError if the name is taken,
        FailedPreconditionError for another descriptor version, InvalidArgumentError /
        DataLossError for a damaged export. Never retried."""
        chunks = _gallery_file.read_chunks(file, _pb.GalleryExportChunk)
        first = next(chunks, None)  # ValueError now for a file that is not an export
        source_error = []

        def requests():
            try:
                chunk, request = first, _pb.ImportGalleryRequest(name=name)
                while chunk is not None:
                    request.chunk.CopyFrom(chunk)
                    yield request
                    chunk, request = next(chunks, None), _pb.ImportGalleryRequest()
            except Exception as e:  # cancels the call: the server must not commit a part
                source_error.append(e)
                raise

        def attempt(remaining):
            return self._stub.ImportGallery(requests(), timeout=remaining,
                                            metadata=self._metadata)

        try:
            response = self._call(False, attempt, timeout)
        except ShapeidError:
            if source_error:
                raise source_error[0] from None
            raise
        return _results.Gallery.from_proto(response)

    # -----------------------------------------------------------------------------------------
    # The server

    def list_descriptors(self, *, timeout=None):
        """The descriptors the server offers, with their parameters and defaults."""
        response = self._unary(True, self._stub.ListDescriptors, _pb.ListDescriptorsRequest(),
                               timeout)
        return [_results.DescriptorKind.from_proto(d) for d in response.descriptors]

    def get_server_stats(self, *, timeout=None):
        """A live summary of the server that answers (ServerStats). Read scope."""
        response = self._unary(True, self._stub.GetServerStats, _pb.GetServerStatsRequest(),
                               timeout)
        return _results.ServerStats.from_proto(response)

    def set_log_level(self, level, *, timeout=None):
        """Sets the answering server's log level ("debug", "info", "warning", "error") until
        it restarts; returns a LogLevel (previous and new). Admin scope."""
        response = self._unary(True, self._stub.SetLogLevel, _pb.SetLogLevelRequest(level=level),
                               timeout)
        return _results.LogLevel(response.previous_level, response.level)

    def health(self, *, timeout=None):
        """grpc.health.v1 Check of the whole server as a Health (`.serving` is True when it
        answers SERVING). UnavailableError when it cannot be reached. Needs no key."""
        reply = self._unary(True, self._health_check, b"", timeout)
        # HealthCheckResponse: field 1 (status), a varint; absent means UNKNOWN (0).
        status = reply[1] if len(reply) >= 2 and reply[0] == 0x08 else 0
        return _results.Health(_HEALTH_STATUSES.get(status, "UNKNOWN"))

    # -----------------------------------------------------------------------------------------

    def _call(self, retry, attempt, timeout, may_retry=None):
        """Runs attempt(remaining_seconds) until it returns, retrying (when `retry`) while it
        raises UNAVAILABLE or CANCELLED, all within one deadline, as the C++ client's Call.
        `may_retry`, when given, is asked before each further attempt (False: stop)."""
        budget = self._deadline if timeout is None else timeout
        if budget <= 0:
            raise ValueError("timeout must be positive (seconds), got %r" % (timeout,))
        deadline = time.monotonic() + budget
        backoff = self._initial_backoff
        attempts = self._max_attempts if retry else 1
        error = None
        for i in range(attempts):
            if i > 0:
                if may_retry is not None and not may_retry():
                    break
                if time.monotonic() + backoff >= deadline:
                    break  # the last answer stands
                time.sleep(backoff)
                backoff *= 2
            try:
                return attempt(max(deadline - time.monotonic(), 0.0))
            except grpc.RpcError as e:
                error = e
                if e.code() not in _RETRIED:
                    break
        raise from_rpc_error(error, self._max_receive_bytes) from None

    def _unary(self, retry, method, request, timeout):
        return self._call(retry, lambda remaining: method(
            request, timeout=remaining, metadata=self._metadata), timeout)

    def _cloud_call(self, header, encoded, one_message, stream_request, unary, stream, timeout,
                    stream_if_unimplemented=True):
        """Describe, Classify and RecognizeScene: the header and the cloud in one message when
        the cloud has at most chunk_points points (and the server knows the one-message
        calls), else a stream of the header then chunks. Retried like any idempotent call.
        stream_if_unimplemented=False: a server without the one-message call has neither
        (RecognizeScene and RecognizeSceneCloud came together), so UNIMPLEMENTED is raised."""
        if (encoded.num_points <= self._chunk_points
                and not self._server_lacks_one_message_calls):
            request = one_message(header=header, points=_pb.PointChunk(xyz=encoded.tobytes()))
            try:
                return self._unary(True, unary, request, timeout)
            except ShapeidError as e:
                if e.code != grpc.StatusCode.UNIMPLEMENTED or not stream_if_unimplemented:
                    raise
                self._server_lacks_one_message_calls = True

        def requests():
            yield stream_request(header=header)
            for chunk in encoded.chunks(self._chunk_points):
                yield stream_request(points=_pb.PointChunk(xyz=chunk))

        return self._call(True, lambda remaining: stream(
            requests(), timeout=remaining, metadata=self._metadata), timeout)


def _identity(value):
    return value


def _set_format(header, encoded, drop_non_finite, frame):
    """Sets `header`'s layout (for a cloud not in the default packed float32) and sensor
    frame (when given)."""
    layout = encoded.layout
    if layout != _clouds.PACKED_XYZ32:
        out = header.layout
        out.point_step = layout.point_step
        for coordinate, offset, datatype in zip((out.x, out.y, out.z), layout.offsets,
                                                layout.datatypes):
            coordinate.offset = offset
            coordinate.datatype = datatype
        out.is_bigendian = layout.big_endian
        out.width = layout.width
        out.row_step = layout.row_step
        out.drop_nonfinite = bool(drop_non_finite)
    if frame is not None:
        header.sensor_frame.CopyFrom(frame)


def _set_optional(message, **values):
    """Sets each field of `message` named by a keyword to its value, leaving those whose
    value is None unset (proto3 optional: the server's default). A value the field cannot
    hold is a ValueError naming the keyword."""
    for name, value in values.items():
        if value is None:
            continue
        try:
            setattr(message, name, value)
        except (TypeError, ValueError) as e:
            raise ValueError("%s=%r: %s" % (name, value, e)) from None


def _region(region):
    """`region` as two rows of 3 floats (min, max); ValueError for another shape. Whether min
    lies below max is the server's to say."""
    try:
        box = np.asarray(region, dtype=np.float64)
    except (TypeError, ValueError):
        box = None
    if box is None or box.shape != (2, 3):
        raise ValueError("region must be ((min x, y, z), (max x, y, z)), got %r" % (region,))
    return box.tolist()


def _sensor_frame(up, transform):
    """A SensorFrame for `up` or `transform` (see Client.classify), None for neither;
    ValueError for both or a wrong shape. Whether the numbers make a direction or a rigid
    transform is the server's to say (InvalidArgumentError with its message)."""
    if up is None and transform is None:
        return None
    if up is not None and transform is not None:
        raise ValueError("give up or transform, not both (a transform fixes up too)")
    if up is not None:
        try:
            values = np.asarray(up, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError("up must be 3 numbers (x, y, z), got %r" % (up,)) from None
        if values.shape != (3,):
            raise ValueError("up must be 3 numbers (x, y, z), got shape %s" % (values.shape,))
        return _pb.SensorFrame(up=values.tolist())
    try:
        matrix = np.asarray(transform, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError("transform must be a 3 x 4 or 4 x 4 array of numbers, got %r"
                         % (transform,)) from None
    if matrix.shape == (4, 4):
        if not np.array_equal(matrix[3], [0.0, 0.0, 0.0, 1.0]):
            raise ValueError("transform is 4 x 4 but its last row is %s, not [0, 0, 0, 1]: "
                             "not a rigid transform" % (matrix[3].tolist(),))
        matrix = matrix[:3]
    elif matrix.shape != (3, 4):
        raise ValueError("transform must be 3 x 4 or 4 x 4 ([R | t]), got shape %s"
                         % (matrix.shape,))
    return _pb.SensorFrame(transform=matrix.reshape(-1).tolist())


def _choice(value, table, what):
    if value not in table:
        raise ValueError("%s must be one of %s, got %r" % (what, ", ".join(table), value))
    return table[value]


def _as_cloud_list(clouds):
    """`clouds` as a list of clouds: one cloud alone, a 3-D array's first axis, or a
    sequence."""
    if isinstance(clouds, np.ndarray):
        return list(clouds) if clouds.ndim == 3 else [clouds]
    if hasattr(clouds, "points") or _clouds._looks_like_point_cloud2(clouds):
        return [clouds]
    try:
        return list(clouds)
    except TypeError:
        raise TypeError("clouds must be a cloud or a sequence of clouds, got %s"
                        % type(clouds).__name__) from None
