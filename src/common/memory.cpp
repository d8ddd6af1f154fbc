#include "common/memory.h"

#include <malloc.h>

namespace ii {

void keep_large_allocations() {
#if defined(__GLIBC__)
  mallopt(M_MMAP_THRESHOLD, 1 << 30);  // serve blocks below 1 GiB from the heap
  mallopt(M_TRIM_THRESHOLD, 1 << 30);  // and keep up to 1 GiB of free heap mapped
  mallopt(M_TOP_PAD, 64 << 20);
#endif
}

}  // namespace ii
