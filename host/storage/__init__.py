"""Storage below every room of the host: typed, versioned JSON results (:mod:`.versioned_json`), the size limits
an input file is held to (:mod:`.limits`), the rule of printed JSON (:mod:`.json_text`) and PNG figures written
atomically (:mod:`.png_figure`). It imports nothing of the host but its errors, so that ``files``,
``accelerometer`` and the rest can all build on it."""
