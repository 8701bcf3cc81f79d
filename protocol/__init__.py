"""The contract between the gait logger and its host.

The written specification is ``protocol/PROTOCOL.md``; the modules of this package are its executable
form (construct declarations for frames and headers, numpy for bulk sample payloads). This package
imports no other package of the project.
"""
