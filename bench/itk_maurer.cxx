// ITK's SignedMaurerDistanceMapImageFilter on a label map, for
// bench/image_sdf.sh's comparison (built by `make bench` only, when
// Debian's libinsighttoolkit5-dev is installed).
//   itk_maurer LABEL.nrrd [OUT.nrrd]
// Prints the filter's wall seconds (reading and writing aside).
#include <chrono>
#include <cstdio>

#include "itkImage.h"
#include "itkImageFileReader.h"
#include "itkImageFileWriter.h"
#include "itkNrrdImageIOFactory.h"
#include "itkSignedMaurerDistanceMapImageFilter.h"

int main(int argc, char **argv)
{
    if (argc < 2) {
        std::fprintf(stderr, "usage: itk_maurer LABEL.nrrd [OUT.nrrd]\n");
        return 1;
    }
    itk::NrrdImageIOFactory::RegisterOneFactory();
    using Label = itk::Image<unsigned char, 3>;
    using Distance = itk::Image<float, 3>;
    auto reader = itk::ImageFileReader<Label>::New();
    reader->SetFileName(argv[1]);
    try {
        reader->Update();
    } catch (const itk::ExceptionObject &e) {
        std::fprintf(stderr, "itk_maurer: %s\n", e.GetDescription());
        return 1;
    }
    auto filter = itk::SignedMaurerDistanceMapImageFilter<Label, Distance>::New();
    filter->SetInput(reader->GetOutput());
    filter->SetUseImageSpacing(true);
    filter->SetSquaredDistance(false);
    filter->SetInsideIsPositive(false);
    filter->SetBackgroundValue(0);
    auto t0 = std::chrono::steady_clock::now();
    filter->Update();
    double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("%.3f\n", s);
    if (argc > 2) {
        auto writer = itk::ImageFileWriter<Distance>::New();
        writer->SetFileName(argv[2]);
        writer->SetInput(filter->GetOutput());
        writer->Update();
    }
    return 0;
}
