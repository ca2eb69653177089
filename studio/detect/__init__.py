"""People detectors: ``studio.detect.image`` (panorama boxes, keypoints) and ``studio.detect.laser``."""
