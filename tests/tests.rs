mod fit;
mod signal;
