"""Images as numbers, no GL: display encoding, comparisons, error metrics, non-finite pixels, term-view scales."""
