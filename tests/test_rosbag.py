"""Episode MCAP logs (``imitation.rosbag``): a constructed 20-step episode read back with the mcap
reader and the ROS 2 decoder (topics, schemas, counts, every field), the rosbag2 schema layout, time
order, and crash safety."""

import math
from collections import Counter, defaultdict

import cv2
import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from imitation import rosbag, storage

N_STEPS = 20
DT = 0.1
WIDTH, HEIGHT = 64, 48
K = np.array([[50.0, 0.0, 31.5], [0.0, 50.0, 23.5], [0.0, 0.0, 1.0]])
# A camera 3 m above the floor looking straight down (OpenCV axes: z forward, y down the image).
CAMERA_ROTATION = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])
CAMERA_POSITION = np.array([0.2, -0.1, 3.0])
MARKER_RVEC = np.array([0.3, -0.2, 0.1])
MARKER_TVEC = np.array([0.1, 0.05, 2.5])


def student_pose(i):
    # The yaw runs from -3 to 2.7 rad: the quaternions cross the +-pi seam.
    return (0.1 * i, -0.05 * i, -3.0 + 0.3 * i)


def teacher_pose(i):
    return (1.0 - 0.02 * i, 0.5, 1.0 - 0.1 * i)


def image(i):
    """Returns a frame whose left half is pure red and right half pure blue (RGB)."""
    frame = np.zeros((HEIGHT, WIDTH, 3), np.uint8)
    frame[:, : WIDTH // 2, 0] = 255
    frame[:, WIDTH // 2 :, 2] = 255
    frame[0, 0, 1] = i  # each frame differs
    return frame


def marker_matrix(i):
    transform = np.eye(4)
    transform[:3, :3] = cv2.Rodrigues(np.array([0.0, 0.0, 0.1 * i]))[0]
    transform[:3, 3] = (0.0, 0.1 * i, 2.0)
    return transform


def record_episode(path):
    with rosbag.EpisodeRecorder(path) as recorder:
        for i in range(N_STEPS):
            recorder.record(
                i * DT,
                cmd_vel=(0.01 * i, -0.02 * i),
                student_pose=student_pose(i),
                student_velocity=(0.3, -0.1 * i),
                teacher_pose=teacher_pose(i),
                image=image(i),
                camera_matrix=K,
                camera_pose=(CAMERA_ROTATION, CAMERA_POSITION),
                marker_poses=[
                    marker_matrix(i),
                    (MARKER_RVEC, MARKER_TVEC),
                    (CAMERA_ROTATION, MARKER_TVEC),
                ],
                estimated_poses={
                    "teacher": teacher_pose(i),
                    "student": None if i == 5 else student_pose(i),
                },
                word=("go", "pick", "lift")[i % 3],
                directive=f"directive {i}",
            )


def read(path, log_time_order=True):
    """Returns ``[(topic, schema, channel, message record, decoded)]`` of an MCAP file."""
    with open(path, "rb") as handle:
        reader = make_reader(handle, decoder_factories=[DecoderFactory()])
        return [
            (channel.topic, schema, channel, message, decoded)
            for schema, channel, message, decoded in reader.iter_decoded_messages(
                log_time_order=log_time_order
            )
        ]


@pytest.fixture(scope="module")
def episode(tmp_path_factory):
    path = tmp_path_factory.mktemp("episode") / "episode.mcap"
    record_episode(path)
    messages = read(path)
    by_topic = defaultdict(list)
    for topic, _, _, record, decoded in messages:
        by_topic[topic].append((record, decoded))
    return path, messages, by_topic


def quaternion_yaw(q):
    return math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y**2 + q.z**2))


def quaternion_matrix(q):
    x, y, z, w = q.x, q.y, q.z, q.w
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def wrapped(angle):
    return math.remainder(angle, 2 * math.pi)


def test_topics_types_and_counts(episode):
    path, messages, by_topic = episode
    expected = {
        "/cmd_vel": "geometry_msgs/msg/TwistStamped",
        "/odom": "nav_msgs/msg/Odometry",
        "/tf": "tf2_msgs/msg/TFMessage",
        "/camera/image/compressed": "sensor_msgs/msg/CompressedImage",
        "/camera/camera_info": "sensor_msgs/msg/CameraInfo",
        "/markers": "geometry_msgs/msg/PoseArray",
        "/robots/teacher/pose": "geometry_msgs/msg/PoseStamped",
        "/robots/student/pose": "geometry_msgs/msg/PoseStamped",
        "/word": "std_msgs/msg/String",
        "/directive": "std_msgs/msg/String",
    }
    types = {topic: schema.name for topic, schema, *_ in messages}
    assert types == expected
    assert {(s.encoding, c.message_encoding) for _, s, c, *_ in messages} == {("ros2msg", "cdr")}
    counts = Counter(topic for topic, *_ in messages)
    assert counts == {t: N_STEPS - (t == "/robots/student/pose") for t in expected}
    with open(path, "rb") as handle:
        reader = make_reader(handle)
        summary, profile = reader.get_summary(), reader.get_header().profile
    assert summary.statistics.message_count == len(messages)
    assert {c.compression for c in summary.chunk_indexes} == {"zstd"}
    assert profile == "ros2"


def test_messages_in_time_order_with_matching_stamps(episode):
    path, _, by_topic = episode
    in_file = [record.log_time for *_, record, _ in read(path, log_time_order=False)]
    assert in_file == sorted(in_file)
    for topic, entries in by_topic.items():
        times = [record.log_time for record, _ in entries]
        assert times == sorted(times) and len(set(times)) == len(times), topic
        for record, decoded in entries:
            if topic in ("/word", "/directive"):
                continue
            header = decoded.transforms[0].header if topic == "/tf" else decoded.header
            assert header.stamp.sec * 10**9 + header.stamp.nanosec == record.log_time
    expected = [round(i * DT * 1e9) for i in range(N_STEPS)]
    assert [record.log_time for record, _ in by_topic["/cmd_vel"]] == expected


def test_cmd_vel_and_odometry(episode):
    _, _, by_topic = episode
    for i, (_, twist) in enumerate(by_topic["/cmd_vel"]):
        assert twist.header.frame_id == "base_link"
        assert twist.twist.linear.x == pytest.approx(0.01 * i)
        assert twist.twist.angular.z == pytest.approx(-0.02 * i)
        assert (twist.twist.linear.y, twist.twist.linear.z) == (0.0, 0.0)
    for i, (_, odometry) in enumerate(by_topic["/odom"]):
        x, y, yaw = student_pose(i)
        assert (odometry.header.frame_id, odometry.child_frame_id) == ("odom", "base_link")
        pose = odometry.pose.pose
        assert (pose.position.x, pose.position.y, pose.position.z) == pytest.approx((x, y, 0.0))
        q = pose.orientation
        assert q.x**2 + q.y**2 + q.z**2 + q.w**2 == pytest.approx(1.0)
        assert quaternion_yaw(q) == pytest.approx(wrapped(yaw), abs=1e-9)
        assert odometry.twist.twist.linear.x == pytest.approx(0.3)
        assert odometry.twist.twist.angular.z == pytest.approx(-0.1 * i)
        assert len(odometry.pose.covariance) == len(odometry.twist.covariance) == 36


def test_transforms(episode):
    _, _, by_topic = episode
    for i, (_, message) in enumerate(by_topic["/tf"]):
        frames = {(t.header.frame_id, t.child_frame_id): t.transform for t in message.transforms}
        assert set(frames) == {
            ("map", "odom"),
            ("odom", "base_link"),
            ("map", "teacher/base_link"),
            ("map", "camera"),
        }
        assert quaternion_matrix(frames["map", "odom"].rotation) == pytest.approx(np.eye(3))
        for key, (x, y, yaw) in (
            (("odom", "base_link"), student_pose(i)),
            (("map", "teacher/base_link"), teacher_pose(i)),
        ):
            t = frames[key]
            assert (t.translation.x, t.translation.y) == pytest.approx((x, y))
            assert quaternion_yaw(t.rotation) == pytest.approx(wrapped(yaw), abs=1e-9)
        camera = frames["map", "camera"]
        assert quaternion_matrix(camera.rotation) == pytest.approx(CAMERA_ROTATION, abs=1e-12)
        translation = (camera.translation.x, camera.translation.y, camera.translation.z)
        assert translation == pytest.approx(CAMERA_POSITION)


def test_camera_image_and_info(episode):
    _, _, by_topic = episode
    for _, message in by_topic["/camera/image/compressed"]:
        assert (message.header.frame_id, message.format) == ("camera", "jpeg")
        bgr = cv2.imdecode(np.frombuffer(bytes(message.data), np.uint8), cv2.IMREAD_COLOR)
        assert bgr.shape == (HEIGHT, WIDTH, 3)
        rgb = bgr[:, :, ::-1].astype(int)
        # Red stays red and blue stays blue: the channels are not swapped.
        assert np.abs(rgb[HEIGHT // 2, 8] - (255, 0, 0)).max() < 20
        assert np.abs(rgb[HEIGHT // 2, WIDTH - 8] - (0, 0, 255)).max() < 20
    for _, info in by_topic["/camera/camera_info"]:
        assert info.header.frame_id == "camera"
        assert (info.width, info.height) == (WIDTH, HEIGHT)
        assert info.distortion_model == "plumb_bob"
        assert list(info.d) == [0.0] * 5
        assert np.reshape(info.k, (3, 3)) == pytest.approx(K)
        assert np.reshape(info.r, (3, 3)) == pytest.approx(np.eye(3))
        assert np.reshape(info.p, (3, 4)) == pytest.approx(np.hstack([K, np.zeros((3, 1))]))


def test_markers_and_estimated_poses(episode):
    _, _, by_topic = episode
    for i, (_, message) in enumerate(by_topic["/markers"]):
        assert message.header.frame_id == "camera"
        assert len(message.poses) == 3
        expected = [
            (marker_matrix(i)[:3, :3], marker_matrix(i)[:3, 3]),
            (cv2.Rodrigues(MARKER_RVEC)[0], MARKER_TVEC),
            (CAMERA_ROTATION, MARKER_TVEC),
        ]
        for pose, (rotation, position) in zip(message.poses, expected, strict=True):
            assert quaternion_matrix(pose.orientation) == pytest.approx(rotation, abs=1e-12)
            p = pose.position
            assert (p.x, p.y, p.z) == pytest.approx(position)
    teacher = by_topic["/robots/teacher/pose"]
    student = by_topic["/robots/student/pose"]
    student_steps = [i for i in range(N_STEPS) if i != 5]
    for steps, entries, truth in (
        (range(N_STEPS), teacher, teacher_pose),
        (student_steps, student, student_pose),
    ):
        for i, (record, message) in zip(steps, entries, strict=True):
            x, y, yaw = truth(i)
            assert record.log_time == round(i * DT * 1e9)
            assert message.header.frame_id == "map"
            assert (message.pose.position.x, message.pose.position.y) == pytest.approx((x, y))
            assert quaternion_yaw(message.pose.orientation) == pytest.approx(wrapped(yaw))


def test_strings(episode):
    _, _, by_topic = episode
    assert [m.data for _, m in by_topic["/word"]] == [
        ("go", "pick", "lift")[i % 3] for i in range(N_STEPS)
    ]
    assert [m.data for _, m in by_topic["/directive"]] == [f"directive {i}" for i in range(N_STEPS)]


def test_schema_in_rosbag2_layout(episode):
    """The concatenated definition as rosbag2 writes it: the type's .msg first, then each dependency
    once, depth first in sorted order, after 80 '=' and ``MSG: pkg/Name``."""
    line = "=" * 80
    assert rosbag.message_definition("geometry_msgs/msg/TwistStamped") == (
        "std_msgs/Header header\nTwist twist\n"
        f"\n{line}\nMSG: geometry_msgs/Twist\nVector3  linear\nVector3  angular\n"
        f"\n{line}\nMSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n"
        f"\n{line}\nMSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n"
        f"\n{line}\nMSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n"
    )
    odometry = rosbag.message_definition("nav_msgs/msg/Odometry")
    blocks = [b.split("\n", 1)[0] for b in odometry.split(f"{line}\nMSG: ")[1:]]
    assert blocks == [
        "geometry_msgs/PoseWithCovariance",
        "geometry_msgs/Pose",
        "geometry_msgs/Point",
        "geometry_msgs/Quaternion",
        "geometry_msgs/TwistWithCovariance",
        "geometry_msgs/Twist",
        "geometry_msgs/Vector3",
        "std_msgs/Header",
        "builtin_interfaces/Time",
    ]
    _, messages, _ = episode
    for _, schema, *_ in messages:
        assert schema.data.decode() == rosbag.message_definition(schema.name)
    with pytest.raises(ValueError, match="allowed"):
        rosbag.message_definition("sensor_msgs/msg/Image")


@pytest.mark.parametrize(
    "rotation",
    [
        np.eye(3),
        np.diag([1.0, -1.0, -1.0]),  # half turns: every branch of the quaternion formula
        np.diag([-1.0, 1.0, -1.0]),
        np.diag([-1.0, -1.0, 1.0]),
        cv2.Rodrigues(np.array([2.0, -1.0, 0.5]))[0],
        cv2.Rodrigues(np.array([0.0, 3.1, 0.2]))[0],
    ],
)
def test_rotation_quaternion_round_trip(tmp_path, rotation):
    with rosbag.EpisodeRecorder(tmp_path / "r.mcap") as recorder:
        recorder.record(0.0, marker_poses=[(rotation, (0.0, 0.0, 1.0))])
    [message] = [decoded for *_, decoded in read(tmp_path / "r.mcap")]
    assert quaternion_matrix(message.poses[0].orientation) == pytest.approx(rotation, abs=1e-12)


def test_unclosed_episode_leaves_no_file(tmp_path):
    path = tmp_path / "crash.mcap"
    recorder = rosbag.EpisodeRecorder(path)
    recorder.record(0.0, cmd_vel=(0.1, 0.0), word="go")
    recorder.record(0.1, image=image(0), camera_matrix=K)
    assert not path.exists()
    assert storage.temporary_name(path).exists()
    recorder.close()
    assert path.exists() and not storage.temporary_name(path).exists()
    assert Counter(topic for topic, *_ in read(path)) == {
        "/cmd_vel": 1,
        "/word": 1,
        "/camera/image/compressed": 1,
        "/camera/camera_info": 1,
    }


def test_failed_episode_is_dropped(tmp_path):
    path = tmp_path / "failed.mcap"
    with pytest.raises(RuntimeError, match="trial failed"):
        with rosbag.EpisodeRecorder(path) as recorder:
            recorder.record(0.0, cmd_vel=(0.1, 0.0))
            raise RuntimeError("trial failed")
    assert not path.exists()
    assert not storage.temporary_name(path).exists()


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"cmd_vel": (0.1, float("nan"))}, "cmd_vel"),
        ({"student_pose": (1.0, 2.0)}, "student_pose"),
        ({"student_velocity": (0.1, 0.0)}, "needs student_pose"),
        ({"image": np.zeros((4, 4, 3))}, "uint8"),
        ({"camera_matrix": K}, "needs an image"),
        ({"marker_poses": [np.eye(3)]}, "marker_poses"),
        ({"marker_poses": [(2 * np.eye(3), (0, 0, 1))]}, "rotation"),
        ({"estimated_poses": {"the teacher": (0, 0, 0)}}, "robot names"),
        ({"word": 3}, "word"),
    ],
)
def test_bad_input_raises_and_writes_nothing(tmp_path, kwargs, match):
    path = tmp_path / "bad.mcap"
    with rosbag.EpisodeRecorder(path) as recorder:
        recorder.record(0.5, word="go")
        with pytest.raises(ValueError, match=match):
            recorder.record(0.6, **{"cmd_vel": (0.2, 0.0), **kwargs})
        with pytest.raises(ValueError, match="time_s"):
            recorder.record(float("nan"), word="go")
        with pytest.raises(ValueError, match="go back"):
            recorder.record(0.4, word="go")
    assert [topic for topic, *_ in read(path)] == ["/word"]
    with pytest.raises(ValueError, match="closed"):
        recorder.record(1.0, word="go")
