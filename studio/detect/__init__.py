"""People detectors: ``studio.detect.image`` (panorama boxes + keypoints), ``studio.detect.laser`` (2D scans)."""
