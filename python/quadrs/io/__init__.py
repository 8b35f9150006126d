"""Files: atomic writes and guarded reads (``files``), Parquet frames with sealed JSON metadata
(``parquet``), and what a saved run is (``integrity``)."""
