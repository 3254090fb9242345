"""Measurement data: CSV, socket folders and ROS recordings read into a Dataset."""
