# cmake -DIN=file -DOUT=file.cpp -DSYMBOL=name -P EmbedFile.cmake
# Writes a C++ file defining `extern const char SYMBOL[]` (NUL-terminated) with IN's bytes,
# so kernels ship inside the binary and work from any directory.
file(READ "${IN}" hex HEX)
string(REGEX REPLACE "([0-9a-f][0-9a-f])" "char(0x\\1)," bytes "${hex}")
string(REGEX REPLACE "((char\\(0x..\\),){12})" "\\1\n" bytes "${bytes}")
get_filename_component(name "${IN}" NAME)
file(WRITE "${OUT}.tmp" "// Generated from ${name} by cmake/EmbedFile.cmake. Do not edit.\nnamespace linksight::detail {\nextern const char ${SYMBOL}[];\nconst char ${SYMBOL}[] = {\n${bytes}0x00};\n}  // namespace linksight::detail\n")
file(RENAME "${OUT}.tmp" "${OUT}")
