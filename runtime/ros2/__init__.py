"""Publish-only ROS 2 side: the daemon's world on ROS 2 topics in rmw_zenoh's wire format."""
