"""The pano-mapping table (paper 2.2, Algorithm 2): its entries, sampling, inverse and file."""
