// stb is a header-only library: its implementation is compiled here, with the project's flags,
// so that the sanitizer and fuzzing build instruments the image decoders too (Debian's
// prebuilt libstb.so would be opaque to them).
#define STB_IMAGE_IMPLEMENTATION
#define STB_IMAGE_WRITE_IMPLEMENTATION
#include <stb_image.h>
#include <stb_image_write.h>
