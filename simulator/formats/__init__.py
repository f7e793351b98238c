"""One module per file format, each holding its writer, its reader and its spec: native, antiuav
(Anti-UAV 410/600 and RGB-T), mot (MM-UAV), coco (COCO-video), trident (TRIDENT)."""
