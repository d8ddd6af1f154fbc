#pragma once

namespace ii {

// Keeps freed large blocks in the process heap instead of returning them to the OS. The
// network allocates and frees tensors of tens to hundreds of MB per layer; with glibc's
// defaults each is a fresh mmap whose first touch page-faults, which made matrix products
// 10-30x slower than on reused memory (measured: bf16 q·kᵀ 36 vs 520 GFLOP/s). Call once
// at start-up.
void keep_large_allocations();

}  // namespace ii
