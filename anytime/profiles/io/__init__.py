"""The file formats of profiles, one module each: `profile_file` (`anytime-profile/1`, a
profile), on the family's shared `document` (the YAML: safe reading, positions, writing),
`reader` (field-by-field checks naming file, line and column) and `companion` (the binary
archive of large tables). Dynamic profiles and traces are `anytime.profiles.dynamic_io`.

The names are imported from here; a test that patches a module's constant (`FAST_LOADER`,
`COMPANION_THRESHOLD`) patches it in the module that reads it.
"""

from anytime.profiles.io.companion import COMPANION_THRESHOLD, is_large, place_tables
from anytime.profiles.io.document import (
    FAST_LOADER,
    MAX_CELLS,
    describe,
    plain,
    write_document,
)
from anytime.profiles.io.profile_file import (
    FIELDS,
    FORMAT,
    TABLES,
    load_profile,
    profile_from_dict,
    profile_to_dict,
    read_profile_file,
    save_profile,
)
from anytime.profiles.io.reader import Reader, read_document

__all__ = [
    "COMPANION_THRESHOLD",
    "FAST_LOADER",
    "FIELDS",
    "FORMAT",
    "MAX_CELLS",
    "TABLES",
    "Reader",
    "describe",
    "is_large",
    "load_profile",
    "place_tables",
    "plain",
    "profile_from_dict",
    "profile_to_dict",
    "read_document",
    "read_profile_file",
    "save_profile",
    "write_document",
]
