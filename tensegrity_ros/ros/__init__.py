"""The ROS layer: the ``tensegrity_node`` around the core simulator (interface: msg_docs/).

The only part of the package that imports rclpy or message packages.  The node's wiring
(:mod:`.node`) and, by concern: its parameters (:mod:`.parameters`,
:mod:`.parameter_handling`), its command topics (:mod:`.commands`), its reports of what
happened (:mod:`.event_reports`, :mod:`.incidents`, :mod:`.live_state`), its messages
(:mod:`.conversions`, :mod:`.visuals`, :mod:`.joint_state_names`, :mod:`.qos`) and the
program around it (:mod:`.process`).
"""
