#include "vloc/common/allocator.h"

#include <malloc.h>

namespace vloc {

void KeepLargeBlocksForReuse() {
  constexpr int kMaxMappedBlock = 64 << 20;  // bytes: larger blocks are mapped (and unmapped when freed)
  constexpr int kMaxFreeHeap = 1 << 30;      // bytes of free heap kept before trimming
  mallopt(M_MMAP_THRESHOLD, kMaxMappedBlock);
  mallopt(M_TRIM_THRESHOLD, kMaxFreeHeap);
}

}  // namespace vloc
