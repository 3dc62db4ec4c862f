!> Kinds of reals and integers used throughout iem, each paired with its MPI datatype.
module iem_kinds
  use, intrinsic :: iso_fortran_env, only: real64, int32, int64
  use mpi_f08, only: MPI_Datatype, MPI_DOUBLE_PRECISION, MPI_INTEGER4, MPI_INTEGER8
  implicit none
  private
  public :: wp, ip, i8, mpi_wp, mpi_ip, mpi_i8

  !> Working real kind.
  integer, parameter :: wp = real64
  !> Default integer kind for counts and local indices.
  integer, parameter :: ip = int32
  !> Wide integer kind for global counts and HDF5 sizes.
  integer, parameter :: i8 = int64

contains

  !> MPI datatype matching real(wp).
  function mpi_wp() result(t)
    type(MPI_Datatype) :: t
    t = MPI_DOUBLE_PRECISION
  end function mpi_wp

  !> MPI datatype matching integer(ip).
  function mpi_ip() result(t)
    type(MPI_Datatype) :: t
    t = MPI_INTEGER4
  end function mpi_ip

  !> MPI datatype matching integer(i8).
  function mpi_i8() result(t)
    type(MPI_Datatype) :: t
    t = MPI_INTEGER8
  end function mpi_i8
end module iem_kinds
