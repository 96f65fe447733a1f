#include "bucket/BucketOptions.h"

#include "stream/util/Error.h"

namespace penumbra {

void BucketOptions::validate() const {
    if (buckets < 1 || buckets > kMaxBuckets)
        fail("bucket options", "buckets must be between 1 and {} (got {})", kMaxBuckets, buckets);
    // A buffer must hold one record; past 64 MiB a buffer only wastes memory (writes of a few
    // hundred KiB already run at disk speed).
    constexpr size_t kMaxBuffer = size_t{64} << 20;
    if (writeBufferBytes < kBucketRecordBytes || writeBufferBytes > kMaxBuffer)
        fail("bucket options", "write buffer must be between {} and {} bytes (got {})", kBucketRecordBytes, kMaxBuffer,
             writeBufferBytes);
    if (readBufferBytes < kBucketRecordBytes || readBufferBytes > kMaxBuffer)
        fail("bucket options", "read buffer must be between {} and {} bytes (got {})", kBucketRecordBytes, kMaxBuffer,
             readBufferBytes);
}

}  // namespace penumbra
