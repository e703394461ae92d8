#include "mat_file.hpp"

#include <matio.h>

#include <memory>

#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/dataset/text_io.hpp"

namespace uwbloc::data {

namespace {
struct CloseMat {
  void operator()(mat_t* m) const { Mat_Close(m); }
};
struct FreeVar {
  void operator()(matvar_t* v) const { Mat_VarFree(v); }
};

template <class T>
double element(const matvar_t* v, size_t i) {
  return static_cast<double>(static_cast<const T*>(v->data)[i]);
}
}  // namespace

std::vector<std::vector<double>> readMatMatrix(const std::string& path, const std::string& name) {
  requireRegularFile(path);
  const std::unique_ptr<mat_t, CloseMat> mat(Mat_Open(path.c_str(), MAT_ACC_RDONLY));
  if (!mat) throwInputError(path, 0, "not a MATLAB .mat file that libmatio can read");
  const std::unique_ptr<matvar_t, FreeVar> var(Mat_VarRead(mat.get(), name.c_str()));
  if (!var) throwInputError(path, 0, "no variable '" + name + "'");
  const std::string what = "variable '" + name + "'";
  if (var->rank != 2 || var->isComplex || var->class_type == MAT_C_SPARSE ||
      var->class_type == MAT_C_CELL || var->class_type == MAT_C_STRUCT ||
      var->class_type == MAT_C_CHAR)
    throwInputError(path, 0, what + " is not a real two-dimensional numeric matrix");
  const size_t rows = var->dims[0], cols = var->dims[1];
  if (rows * cols > 100000000) throwInputError(path, 0, what + " is implausibly large");
  if (rows * cols > 0 && !var->data) throwInputError(path, 0, what + " holds no data");
  double (*get)(const matvar_t*, size_t) = nullptr;
  switch (var->data_type) {
    case MAT_T_DOUBLE:
      get = element<double>;
      break;
    case MAT_T_SINGLE:
      get = element<float>;
      break;
    case MAT_T_INT32:
      get = element<int32_t>;
      break;
    case MAT_T_UINT32:
      get = element<uint32_t>;
      break;
    case MAT_T_INT16:
      get = element<int16_t>;
      break;
    case MAT_T_UINT16:
      get = element<uint16_t>;
      break;
    case MAT_T_INT8:
      get = element<int8_t>;
      break;
    case MAT_T_UINT8:
      get = element<uint8_t>;
      break;
    default:
      throwInputError(path, 0, what + " has an element type this reader does not convert");
  }
  std::vector<std::vector<double>> out(rows, std::vector<double>(cols));
  for (size_t c = 0; c < cols; ++c)
    for (size_t r = 0; r < rows; ++r) out[r][c] = get(var.get(), c * rows + r);  // column-major
  return out;
}

}  // namespace uwbloc::data
