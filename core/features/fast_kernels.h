#pragma once
// The two per-pixel kernels of ORB extraction (orb_extractor.h), a row at a
// time: FAST-9 scores and the per-cell non-maximum suppression of those scores.
// Each has an AVX2 path (chosen at run time), an SSE2 path and a scalar one,
// all giving the same bytes; use_avx2 = false forces the narrower paths (tests).
#include <cstddef>
#include <cstdint>

namespace orbatlas {

// ---- FAST-9 on the 16-pixel circle ----
//
// A pixel is a corner at threshold t when 9 contiguous pixels of the circle are
// all brighter than centre + t, or all darker than centre - t. Its score (what
// cv::FAST reports as the response) is the largest t at which it still is one:
// the best over the 16 arcs of 9 of the arc's smallest difference, minus 1.

// The offsets of the radius-3 circle's 16 pixels from its centre, in order
// around it, in an image whose rows are row_step bytes apart.
void fast_circle_offsets(std::ptrdiff_t row_step, std::ptrdiff_t offsets[16]);

// Scores of row[x_begin, x_end) into out[x_begin, x_end). Pixels that cannot be
// corners at min_threshold may get 0 instead of their score. Reads 3 pixels
// (and rows) around each pixel scored.
void fast_score_row(const std::uint8_t* row, const std::ptrdiff_t* offsets, int x_begin, int x_end, std::uint8_t* out,
                    int min_threshold, bool use_avx2);

// ---- Non-maximum suppression, a row of a band of cells at a time ----
//
// cv::FAST on a cell's window keeps a corner that scores strictly above each of
// its 8 neighbours, and sees nothing outside the window: a neighbour in another
// cell does not count. A neighbour scoring below the threshold never decides
// (the corner itself scores at least the threshold), so the level's scores are
// used as they are, the neighbours across a cell's edge masked out.

// Bit x of bits for each x in [x_begin, x_end) where row[x] is a corner of its
// cell at `threshold` (left_ok[x] / right_ok[x]: 0xff where pixel x - 1 / x + 1
// lies in x's cell; up / down: the rows around, zeros outside the cell). Reads
// [x_begin - 1, x_end + 1) of each row and of the masks; sets bits, never clears them.
void maxima_row(const std::uint8_t* up, const std::uint8_t* row, const std::uint8_t* down, const std::uint8_t* left_ok,
                const std::uint8_t* right_ok, int x_begin, int x_end, int threshold, std::uint64_t* bits,
                bool use_avx2);

}  // namespace orbatlas
