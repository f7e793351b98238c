"""One module per file format, each holding its writer, its reader and its spec (docs/FORMATS.md):
native, antiuav (Anti-UAV 410/600, RGB-T, 2021), mot (MM-UAV + the MOTChallenge evaluation layout),
coco (COCO-video), trident (generated and public TRIDENT layouts), sigmf (RF I/Q), webdataset
(tar shards); validation holds the readers' shared error and strict/non-strict rules."""
