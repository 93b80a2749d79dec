"""The QoS of the node's topics (documented in msg_docs/ and README.md)."""
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

#: Commands: reliable + volatile, so ``ros2 topic pub`` (and any default publisher)
#: matches.  Depth 1000 = 0.2 s of a 5 kHz stream, the longest a command crossing a fold
#: keeps the node busy on a loaded machine; each callback then reads everything waiting
#: (coalescing superseded targets beyond its time budget), so the queue does not overflow.
COMMAND_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.VOLATILE)
#: Latched status (``stable``, ``equilibrium``): a late subscriber gets the current one.
STATUS_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                        reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: ``jumps``: the last 10 jumps are kept for late subscribers.
JUMPS_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                       reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: ``joint_states`` and ``/diagnostics``: the usual reliable, volatile stream.
STATE_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                       reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.VOLATILE)
#: ``head_pose``: latched (depth 1), like the status topics: a late subscriber gets the
#: current head pose at once.  Published on every publish_rate tick, at start-up and reset.
HEAD_QOS = STATUS_QOS
#: ``markers``: latched too, so RViz started later still draws the mechanism.
MARKERS_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: ``motion``: latched, so a client that subscribes after sending a trajectory still
#: sees how it ended.
MOTION_QOS = STATUS_QOS
#: ``/tf``: what tf2_ros's TransformBroadcaster uses (DynamicBroadcasterQoS).
TF_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                    reliability=ReliabilityPolicy.RELIABLE,
                    durability=DurabilityPolicy.VOLATILE)


def equilibrium_qos(modules):
    """``equilibrium``: one latched status per module, published all N together; depth N
    keeps every module's latest for a late subscriber (N = 1: depth 1, as STATUS_QOS)."""
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=modules,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL)
