#pragma once
// Internal to the vocabulary library: runs slices of work on a few threads that
// take the next slice from an atomic index (the calling thread works too).
#include <cstddef>
#include <functional>

namespace orbatlas::vocabulary_detail {

// Calls fn(chunk, begin, end) for the `chunks` near-equal slices of [0, n), on up
// to `threads` threads. Returns when all are done; rethrows the first exception.
void run_chunks(std::size_t n, std::size_t chunks, int threads,
                const std::function<void(std::size_t chunk, std::size_t begin, std::size_t end)>& fn);

}  // namespace orbatlas::vocabulary_detail
