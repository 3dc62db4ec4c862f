!> The force kernel's row copies written with AVX2 vectors (iem_kernel_rows_simd.c): a chunk's
!> node rows gathered out of the state and its corner forces added to the node rows' forces,
!> bit for bit as iem_kernel_rows' loops do them, which run where the C file is built without
!> AVX2 (docs/architecture.md, "The force kernel").
module iem_kernel_simd
  use, intrinsic :: iso_c_binding, only: c_int, c_double
  implicit none
  private
  public :: kernel_simd, use_kernel_simd, c_gather_row4, c_scatter_rows

  !> Whether the copies of iem_kernel_rows_simd.c are used when built (tests clear it to
  !> compare them with the Fortran loops).
  logical :: use_kernel_simd = .true.

  interface
    !> 1 when iem_kernel_rows_simd.c's copies are built (AVX2), else 0.
    pure integer(c_int) function c_simd() bind(c, name='iem_kernel_rows_simd')
      import :: c_int
    end function c_simd
    !> w(i, 1:2) = y(r0 + 1:r0 + 2, i) for the nodes i = 0..m of a block of consecutive nodes
    !> (4 values a node; w of leading dimension ld), where built.
    pure subroutine c_gather_row4(m, y, r0, ld, w) bind(c, name='iem_gather_row4')
      import :: c_int, c_double
      integer(c_int), value :: m, r0, ld
      real(c_double), intent(in) :: y(*)
      real(c_double), intent(inout) :: w(*)
    end subroutine c_gather_row4
    !> iem_kernel_rows' add_block_forces (fx, fy of leading dimension ldf), where built.
    pure subroutine c_scatter_rows(m, fb, ft, fx, fy, ldf) bind(c, name='iem_scatter_rows')
      import :: c_int, c_double
      integer(c_int), value :: m, ldf
      real(c_double), intent(inout) :: fb(*), ft(*)
      real(c_double), intent(in) :: fx(*), fy(*)
    end subroutine c_scatter_rows
  end interface

contains

  !> Whether the copies of iem_kernel_rows_simd.c run (built with AVX2, and use_kernel_simd).
  pure logical function kernel_simd()
    kernel_simd = use_kernel_simd .and. c_simd() == 1
  end function kernel_simd
end module iem_kernel_simd
