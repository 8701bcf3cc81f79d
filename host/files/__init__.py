"""Files and decoding: memory images, dumps and captures into recordings, the IPOL reader, record verification."""
