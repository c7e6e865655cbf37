"""The pipeline's stages, one streaming implementation each, shared by ``generate`` and the nodes.

``reference`` → ``variation`` → ``measurement`` → ``navigation``: each stage takes input
messages (or arrays) in any chunking, carries its state between calls and returns serialized
output messages; ``strapdown_ros.generate`` feeds them piece by piece, the node of the same
name feeds them what it receives. The flow is drawn in docs/architecture.md.
"""
