"""Named request and response models (generated clients read these)."""
