#pragma once
// Allocator settings for programs that fit models.
//
// A fit evaluates the model's FRFs and their derivatives thousands of times, each time in arrays of
// megabytes (frequencies x outputs x inputs x parameters) that live for one evaluation. glibc serves
// such blocks with mmap, or trims them from the heap when freed, so that every evaluation pays page
// faults on fresh memory: in a profile of `diagnose` a third of the time went to the kernel's page
// fault handler. Programs call KeepFreedMemory() once at start-up to have freed blocks kept for reuse.

namespace stagefit {

/// Raises glibc's mmap and trim thresholds (256 MB / 512 MB) so that large blocks come from, and go
/// back to, the heap. The memory a program holds at its peak is then kept until it exits. No effect
/// with another C library.
void KeepFreedMemory();

}  // namespace stagefit
