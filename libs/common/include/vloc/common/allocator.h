#pragma once
// The C allocator of an image-processing process.

namespace vloc {

// Keeps freed blocks of up to 64 MB in the process's heap for the next
// allocation, and up to 1 GB of free heap before it is returned to the
// system. glibc otherwise maps every block over its (adaptive, <= 32 MB)
// threshold fresh and trims the heap above 2x that threshold: a SIFT
// pyramid (tens of MB per level, made and freed per image) then costs a
// page fault per 4 kB at every image, about a fifth of the front end's
// ASIFT time. Peak memory is unchanged; the heap is not shrunk after a
// peak. Call once at the start of main; process-wide (mallopt).
void KeepLargeBlocksForReuse();

}  // namespace vloc
