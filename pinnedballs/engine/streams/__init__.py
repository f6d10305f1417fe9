"""The random streams a chain draws its picks from: xoshiro256** (`xoshiro`, the default) and its jumps
ahead (`jump`, for the threads), and the counter stream Philox4x64-10 (`philox`: the pick of step ``s`` a
function of the seed and ``s``, on any number of threads and on a GPU)."""
