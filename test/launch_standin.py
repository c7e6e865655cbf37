"""The launch API classes the tests' stand-ins of launch / launch_ros share (source text, exec'd
in the test's process or a child's): actions record their arguments; a context is a dict of the
launch arguments and "_prefix" (what FindPackagePrefix finds). Each test appends the modules its
launch file imports (``mods``)."""

LAUNCH_API_CLASSES = """
import sys, types

class _Action:
    def __init__(self, *args, **kwargs):
        self.args, self.kwargs = args, kwargs

class LaunchConfiguration:
    def __init__(self, name):
        self.name = name

    def perform(self, context):
        return context[self.name]

class FindPackagePrefix:
    def __init__(self, package):
        assert package == "strapdown_ros"

    def perform(self, context):
        return context["_prefix"]
"""
