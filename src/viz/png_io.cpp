// PNG through libpng (Debian libpng-dev), written to memory and then atomically to disk.
#include <fmt/format.h>
#include <png.h>

#include <csetjmp>
#include <cstring>
#include <fstream>
#include <sstream>

#include "meshpde/core/errors.h"
#include "meshpde/io/mesh_io.h"
#include "meshpde/viz/render.h"

namespace meshpde {

void write_png(const std::filesystem::path& path, const Image& image) {
  if (image.width <= 0 || image.height <= 0 || image.rgb.size() != 3 * std::size_t(image.width) * image.height)
    throw Error(fmt::format("{}: image buffer does not match its size", path.string()));
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  if (!png || !info) {
    png_destroy_write_struct(&png, &info);
    throw Error("libpng: out of memory");
  }
  std::string bytes;
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    throw Error(fmt::format("{}: libpng failed to encode the image", path.string()));
  }
  png_set_write_fn(
      png, &bytes,
      [](png_structp p, png_bytep data, png_size_t n) {
        static_cast<std::string*>(png_get_io_ptr(p))->append(reinterpret_cast<const char*>(data), n);
      },
      [](png_structp) {});
  png_set_IHDR(png, info, image.width, image.height, 8, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  for (int y = 0; y < image.height; ++y)
    png_write_row(png, const_cast<png_bytep>(image.rgb.data() + 3 * std::size_t(y) * image.width));
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  write_file_atomically(path, bytes);
}

Image read_png(const std::filesystem::path& path) {
  FILE* fp = std::fopen(path.c_str(), "rb");
  if (!fp) throw InputError(fmt::format("{}: cannot open for reading", path.string()));
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  Image img;
  if (!png || !info || setjmp(png_jmpbuf(png))) {
    png_destroy_read_struct(&png, &info, nullptr);
    std::fclose(fp);
    throw InputError(fmt::format("{}: not a readable PNG", path.string()));
  }
  png_init_io(png, fp);
  png_read_info(png, info);
  png_set_strip_16(png);
  png_set_strip_alpha(png);
  png_set_palette_to_rgb(png);
  png_set_gray_to_rgb(png);
  png_read_update_info(png, info);
  img.width = static_cast<int>(png_get_image_width(png, info));
  img.height = static_cast<int>(png_get_image_height(png, info));
  img.rgb.resize(3 * std::size_t(img.width) * img.height);
  for (int y = 0; y < img.height; ++y) png_read_row(png, img.rgb.data() + 3 * std::size_t(y) * img.width, nullptr);
  png_destroy_read_struct(&png, &info, nullptr);
  std::fclose(fp);
  return img;
}

}  // namespace meshpde
