"""The ROS layer: the ``tensegrity_node`` around the core simulator (interface: msg_docs/).

Its wiring (:mod:`.node`), its parameters (:mod:`.parameters`, :mod:`.parameter_handling`),
its message conversions and its interfaces by concern: the command subscriptions, the
reports of the simulator's events, the state and status publishers, the process around
the node.  The only part of the package that imports rclpy or message packages.
"""
