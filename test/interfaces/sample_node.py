"""Child process for test_cross_process: publishes every sample message and serves every service.

Run as ``python sample_node.py PREFIX``; topics and services are PREFIX/<Name>. Publishes all
samples every 50 ms until stopped (SIGINT), so the subscriber needs no timing assumption.
"""

import sys

import rclpy
import samples
from rclpy.executors import ExternalShutdownException
from rclpy.qos import QoSProfile, ReliabilityPolicy

from lander_interfaces import msg, srv


def main() -> None:
    prefix = sys.argv[1]
    rclpy.init()
    node = rclpy.create_node("interfaces_sample_node")
    qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
    pubs = [(node.create_publisher(getattr(msg, n), f"{prefix}/{n}", qos), samples.make_message(n))
            for n in samples.MESSAGES]
    for n in samples.SERVICES:
        node.create_service(getattr(srv, n), f"{prefix}/{n}",
                            lambda req, res, n=n: samples.answer(n, req))
    node.create_timer(0.05, lambda: [p.publish(m) for p, m in pubs])
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
