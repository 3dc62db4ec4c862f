!> pfunit_lite, MPI part: a small stand-in for pFUnit 4's `pfunit` module.
!> Re-exports everything public in funit and adds MpiTestMethod and the MPI test runner.
module pfunit
  use funit
  implicit none
  public    ! so that the names of funit are re-exported; `use mpi` stays local below

  !> What an MPI test receives as `this`: its communicator, its rank and its size.
  type :: MpiTestMethod
    private
    integer :: comm = 0
    integer :: rank = 0
    integer :: npes = 1
  contains
    procedure :: getMpiCommunicator
    procedure :: getProcessRank
    procedure :: getNumProcesses
  end type MpiTestMethod

  abstract interface
    !> An MPI test as the generated wrappers see it.
    subroutine mpi_test(this)
      import :: MpiTestMethod
      class(MpiTestMethod), intent(inout) :: this
    end subroutine mpi_test
  end interface
  private :: mpi_test, getMpiCommunicator, getProcessRank, getNumProcesses

contains

  !> The communicator of the test (an `use mpi` style integer handle).
  integer function getMpiCommunicator(this) result(comm)
    class(MpiTestMethod), intent(in) :: this
    comm = this%comm
  end function getMpiCommunicator

  !> The rank of this process in the test's communicator.
  integer function getProcessRank(this) result(rank)
    class(MpiTestMethod), intent(in) :: this
    rank = this%rank
  end function getProcessRank

  !> The number of processes in the test's communicator.
  integer function getNumProcesses(this) result(npes)
    class(MpiTestMethod), intent(in) :: this
    npes = this%npes
  end function getNumProcesses

  !> Runs an MPI test once for each size in npes, on the first npes ranks of MPI_COMM_WORLD
  !> (made with MPI_Comm_split); a size larger than the world is reported as skipped.
  subroutine pfl_run_mpi(name, npes, test)
    use mpi, only: MPI_COMM_WORLD, MPI_UNDEFINED, MPI_Comm_rank, MPI_Comm_size, &
        MPI_Comm_split, MPI_Comm_free
    character(len=*), intent(in) :: name
    integer, intent(in) :: npes(:)
    procedure(mpi_test) :: test
    type(MpiTestMethod) :: this
    character(len=:), allocatable :: full_name
    integer :: j, n, world_rank, world_size, comm, ierr

    call MPI_Comm_rank(MPI_COMM_WORLD, world_rank, ierr)
    call MPI_Comm_size(MPI_COMM_WORLD, world_size, ierr)
    do j = 1, size(npes)
      n = npes(j)
      full_name = name // '[npes=' // pfl_str(n) // ']'
      if (n < 1 .or. n > world_size) then
        call pfl_skip_test(full_name, 'needs ' // pfl_str(n) // ' ranks, the run has ' // &
            pfl_str(world_size))
        cycle
      end if
      call MPI_Comm_split(MPI_COMM_WORLD, merge(0, MPI_UNDEFINED, world_rank < n), &
          world_rank, comm, ierr)
      if (world_rank >= n) cycle
      this = MpiTestMethod(comm=comm, rank=world_rank, npes=n)
      call pfl_begin_test(full_name)
      call test(this)
      call pfl_end_test(comm)
      call MPI_Comm_free(comm, ierr)
    end do
  end subroutine pfl_run_mpi

end module pfunit
